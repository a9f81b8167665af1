"""The simulated areaDetector driver, feeding its plugins (:mod:`.plugins`).

PVs of the driver ``P:CAM:`` (``P`` the IOC's prefix): ``Exposure``/``_RBV``,
``AcquirePeriod``/``_RBV``, ``NumImages``/``_RBV``, ``ImageMode``/``_RBV``
(Single, Multiple, Continuous), ``TriggerMode``/``_RBV`` (Internal: frames at
the exposure, or period; External: one frame per trigger, see
:meth:`Detector.trigger`), ``Acquire`` (Done/Acquire; a put of Acquire
completes when the acquisition ends; Done stops it), ``Acquire_RBV``,
``Stop`` (a put of 1 ends the acquisition at once: docs/ca.md),
``ArrayCounter``/``_RBV``, ``NumImagesCounter_RBV``, ``ArrayCallbacks``/
``_RBV``, ``Manufacturer_RBV``, ``DetectorState_RBV``, ``Filename`` (a char
waveform, the design document's ``xml``), ``MaxSize`` (frame side).

Every frame the driver makes goes to the plugins whose callbacks are
enabled: the position plugin tags it with the next position (and its
uniqueId), the writer appends it (and its position) to the file with h5py.
A frame's pixels all hold its uniqueId (modulo 65536); an External
frame's, the index + 1 of the point whose trigger made it (the same when
the frame is tagged right), so a frame at a wrong uniqueId shows.

Frames come on an absolute schedule: in Internal mode frame k is due at
the acquisition's start plus k periods (a late frame is made at once, so
lateness does not add up); in External mode a frame is made when its
trigger comes (the trajectory's schedule). The period is at least
:data:`~.pace.MIN_PERIOD`, the shortest this simulation sustains (:mod:`.pace`).
The counters (``ArrayCounter_RBV``, ``NumImagesCounter_RBV``) are posted at
most every :data:`~.pace.STATUS_PERIOD` (:mod:`.pace`), and always
before the ``Acquire`` put completes.
"""

from __future__ import annotations

import asyncio
from typing import Any

import numpy as np
from softioc import builder

from .dispatch import in_place
from .pace import MIN_PERIOD, Schedule, Throttled
from .plugins import (
    TEXT,
    HDFWriter,
    PositionPlugin,
    Stoppable,
    demand,
    enable,
    stop_requested,
)

__all__ = [
    "MIN_PERIOD",
    "Detector",
    "HDFWriter",
    "PositionPlugin",
    "demand",
    "make_detector",
    "stop_requested",
]


class Detector(Stoppable):
    """A simulated detector driver feeding its plugins."""

    def __init__(self, prefix: str, plugins: list[Any]) -> None:
        self.plugins = plugins
        builder.SetDeviceName(f"{prefix}:CAM")
        super().__init__()
        seconds = {"EGU": "s", "PREC": 4, "DRVL": 0.0, "DRVH": 100.0}
        rbv = {"EGU": "s", "PREC": 4}
        self.exposure, _ = demand(
            "Exposure", builder.aOut, builder.aIn, 0.1, **seconds, rbv=rbv
        )
        self.period, _ = demand(
            "AcquirePeriod", builder.aOut, builder.aIn, 0.1, **seconds, rbv=rbv
        )
        self.num_images, _ = demand(
            "NumImages", builder.longOut, builder.longIn, 1, DRVL=1, DRVH=100000000
        )
        self.mode = self._choice("ImageMode", "Single", "Multiple", "Continuous")
        self.trigger_mode = self._choice("TriggerMode", "Internal", "External")
        self.counter_rbv = Throttled(
            builder.longIn("ArrayCounter_RBV", initial_value=0)
        )
        self.counter = builder.longOut(
            "ArrayCounter",
            initial_value=0,
            always_update=True,
            blocking=True,
            on_update=self._put_counter,
        )
        self.images = Throttled(builder.longIn("NumImagesCounter_RBV", initial_value=0))
        self.callbacks, _ = enable("ArrayCallbacks", 1)
        builder.stringIn("Manufacturer_RBV", initial_value="Simulated Detector")
        self.state = builder.mbbIn(
            "DetectorState_RBV", "Idle", "Acquire", "Readout", "Error", initial_value=0
        )
        builder.longStringOut("Filename", length=TEXT, initial_value="")
        self.size = builder.longOut("MaxSize", initial_value=8, DRVL=1, DRVH=256)
        self.acquire_rbv = builder.boolIn(
            "Acquire_RBV", ZNAM="Done", ONAM="Acquire", initial_value=0
        )
        self.acquire = builder.boolOut(
            "Acquire",
            ZNAM="Done",
            ONAM="Acquire",
            on_update=self._acquire,
            blocking=True,
            always_update=True,
        )
        self.triggered = asyncio.Event()
        #: frames wanted of the External acquisition in progress (None: no
        #: limit), frames made so far, and whether one is in progress
        self._external_total: int | None = None
        self._made = 0
        self._taking = False

    def _put_counter(self, value: int) -> None:
        self.counter_rbv.set(value)
        self.counter_rbv.flush()

    def wake(self) -> None:
        self.triggered.set()

    def _counters_done(self) -> None:
        self.counter_rbv.flush()
        self.images.flush()

    @staticmethod
    def _choice(name: str, *labels: str) -> Any:
        readback = builder.mbbIn(f"{name}_RBV", *labels, initial_value=0)
        return builder.mbbOut(
            name,
            *labels,
            initial_value=0,
            always_update=True,
            blocking=True,
            on_update=in_place(readback.set),
        )

    def trigger(self, point: int = -1) -> None:
        """An External trigger (the trajectory reaching ``point``): one frame,
        if acquiring in External mode; dropped otherwise, as hardware does."""
        if not self._taking or self.stopping(self.acquire):
            return
        total = self._external_total
        if total is not None and self._made >= total:
            return
        self._made += 1
        self._frame(self._made, point)
        if total is not None and self._made >= total:
            self.triggered.set()  # the acquisition is complete

    async def _acquire(self, value: int) -> None:
        if not value:
            return
        self.started()
        mode = self.mode.get()
        total = 1 if mode == 0 else self.num_images.get() if mode == 1 else None
        external = self.trigger_mode.get() == 1
        self.triggered.clear()
        self.images.set(0)
        self.images.flush()  # reset before the acquisition shows
        self.acquire_rbv.set(1)
        self.state.set(1)
        try:
            if external:
                await self._external(total)
            else:
                await self._internal(total)
        finally:
            self._taking = False
            self._counters_done()
            self.state.set(0)
            self.acquire_rbv.set(0)

    async def _internal(self, total: int | None) -> None:
        schedule = Schedule()
        deadline = schedule.start
        made = 0
        while total is None or made < total:
            deadline += max(self.exposure.get(), self.period.get(), MIN_PERIOD)
            await schedule.until(deadline)
            if self.stopping(self.acquire):
                break
            made += 1
            self._frame(made)

    async def _external(self, total: int | None) -> None:
        """Frames are made by :meth:`trigger` as the triggers come; this
        waits for the last (or a stop)."""
        self._external_total = total
        self._made = 0
        self._taking = True
        while (total is None or self._made < total) and not self.stopping(self.acquire):
            self.triggered.clear()
            try:
                await asyncio.wait_for(self.triggered.wait(), 0.05)
            except TimeoutError:
                pass

    def _frame(self, made: int, point: int = -1) -> None:
        count = self.counter_rbv.get() + 1
        self.counter_rbv.set(count)
        self.images.set(made)
        if not self.callbacks.get():
            return
        uid, position = count, None
        for plugin in self.plugins:
            if isinstance(plugin, PositionPlugin):
                tagged = plugin.tag()
                if tagged is not None:
                    uid, position = tagged
        side = int(self.size.get())
        # what the detector saw: the point that triggered it, else its uid
        seen = point + 1 if point >= 0 else uid
        frame = np.full((side, side), seen % 65536, dtype=np.uint16)
        for plugin in self.plugins:
            if isinstance(plugin, HDFWriter):
                plugin.write(frame, uid, position)


def make_detector(prefix: str) -> Detector:
    """The driver and its two plugins, under ``prefix``."""
    plugins: list[Any] = [PositionPlugin(prefix), HDFWriter(prefix)]
    return Detector(prefix, plugins)

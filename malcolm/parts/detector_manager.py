"""DetectorManagerPart: a device-layer detector manager over Channel Access.

The part of ``ADCore.DetectorManager`` (docs/devices.md). It drives three
child hardware blocks, a detector driver (``ADCore.DetectorDriver``), a
position plugin (``ADCore.PositionPlugin``) and an HDF5 writer
(``ADCore.HDFWriter``), through a scan:

- **configure** sets the driver (exposure and period from the scan's
  duration, Multiple images, ``numImages``, ``triggerMode``), the writer
  (``<fileDir>/<formatName>.h5``, ``numCapture``) and loads the run's points
  into the position plugin as XML (``<position n="i"/>``, a few thousand per
  put), then **arms**: the plugin running and the writer capturing, and in
  External mode the driver acquiring, waiting for triggers;
- **run** starts the driver (Internal) and waits for the writer's capture,
  the plugin and the driver to finish; progress is the frames written. A
  run that sees no new frame within the frame timeout (configure's
  ``frameTimeout``, else 3 x the longest point + 10 s) stops the children
  and fails, saying what is known (:func:`stall_message`): the manager goes
  to Fault;
- **pause** stops the driver and the plugins (the file is closed); **seek**
  to step k re-arms at k: the plugin's ``idStart`` is k + 1 and its
  positions start at point k, the writer appends to the file;
- **abort** stops everything (the file is closed); a channel lost on the
  way fails the phase with an error naming the PV and the children whose
  health is not OK.

A frame's uniqueId is the point's index + 1 (the plugin's ``idStart`` plus
the positions it has used since it was cleared).
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import os
import time
from typing import Any

from malcolm.core import (
    BadValueError,
    ChoiceMeta,
    MalcolmError,
    NumberMeta,
    StringMeta,
)
from malcolm.fsm import RunnableDevice
from malcolm.hooks import BlockView, Task
from malcolm.io import ChannelError

from .adcore import positions_xml
from .base import Part, PartRegistrar
from .datasets import check_file_args, dataset_rows, datasets_meta

__all__ = ["DetectorManagerPart"]

#: trigger modes of the driver
TRIGGER_MODES = ("Internal", "External")
#: the shortest frame period (s) the detector sustains, its readout time:
#: validate raises a scan's shorter duration to it. The simulated IOC's
#: (``malcolm.sim.beamline_ioc.pace.MIN_PERIOD``) with malcolm following
#: it: it keeps pace at 0.05 ms a point and falls behind at 0.02 ms on this
#: 2-core machine; 0.1 ms leaves room for a loaded one (docs/devices.md)
MIN_EXPOSURE = 0.0001
#: positions per XML put: a char waveform of 65536 bytes holds 2500 of 8 digits
XML_BATCH = 2500
#: seconds to wait for a child to show it is armed or stopped
SETTLE_TIMEOUT = 10.0
#: the frame timeout of a run (configure's ``frameTimeout`` 0):
#: this many times the scan's longest point, plus the margin below, for the
#: motion's run-up and turnarounds (the simulated motors' 0.1 s ACCL makes a
#: snake's turnaround 0.2 s; a real controller's may take seconds)
FRAME_TIMEOUT_FACTOR = 3.0
#: seconds added to the frame timeout (see FRAME_TIMEOUT_FACTOR)
FRAME_TIMEOUT_MARGIN = 10.0
#: areaDetector ``DetectorState_RBV`` values of a driver that is not
#: acquiring (any other: it is; its ``Acquire`` demand may still read
#: Acquire after a Stop, so the state is what tells)
STOPPED_STATES = frozenset({"Idle", "Error", "Aborting", "Aborted", "Disconnected"})
#: HDF5 paths the writer uses
DATA_PATH = "/entry/data"
UID_PATH = "/entry/uid"


#: the XML of the last few batches (a scan configured again, or another of
#: the same size, loads the same batches: 65 kB of text each)
_batch_xml = functools.lru_cache(maxsize=8)(positions_xml)


class FrameClock:
    """When the last new frame of a run was seen: ``count`` frames of the
    scan so far (``first`` at the run's start), at loop time ``since``
    (wall-clock time ``wall``); ``made``: the driver's frame counter (its
    ``arrayCounter``) at that frame, its value at the run's start plus the
    frames counted since.

    ``made`` is not the counter read when the count came: the driver's
    counter and the counting plugin's are posted independently (by a real
    IOC as by the simulation, each at most every few ms), so the plugin's
    count may arrive first. A writer's 31 seen while ``arrayCounter`` still
    read 29 made a stalled run say "made 2 frames since: its frames do not
    reach the writer", when all 31 had reached it."""

    def __init__(self, first: int, made: int = 0) -> None:
        self.first = self.count = first
        self.start_made = self.made = made
        self.since = asyncio.get_running_loop().time()
        self.wall = time.time()

    def saw(self, count: int) -> None:
        if count > self.count:
            self.count = count
            self.made = self.start_made + count - self.first
            self.since = asyncio.get_running_loop().time()
            self.wall = time.time()


def stall_message(
    mri: str,
    bound: float,
    frames: FrameClock,
    mode: str,
    detector_state: str,
    acquiring: bool,
    made: int = 0,
    counted_by: str = "the writer",
    callbacks: bool = True,
) -> str:
    """What a run that saw no new frame within ``bound`` s knows: the frame
    it waited for, the time waited, the last frame that came (and when), the
    trigger mode, whether the driver still acquires and the frames it made
    since (``made``: its counter's advance; ``counted_by`` counts the run's
    frames; ``callbacks``: the driver's arrayCallbacks); and the cause where
    that tells it: frames made since, they do not reach ``counted_by``;
    none made and not acquiring, the detector stopped; none made, External
    and acquiring, the triggers are not arriving."""
    waited = frames.count + 1
    when = time.strftime("%H:%M:%S UTC", time.gmtime(frames.wall))
    if frames.count > frames.first:
        since = f"frame {frames.count}, the last that came ({when})"
    else:
        since = f"the run's start ({when}; no frame of this run came)"
    driver = "still acquiring" if acquiring else "not acquiring"
    text = (
        f"{mri}: no frame {waited} (uniqueId {waited}) within {bound:g} s of"
        f" {since}; trigger mode {mode}; the driver is {driver}"
        f" (detectorState {detector_state}) and made {max(made, 0)} frames since"
    )
    if made > 0:
        off = "" if callbacks else " (the driver's arrayCallbacks is off)"
        return f"{text}: its frames do not reach {counted_by}{off}"
    if not acquiring:
        return f"{text}: the detector stopped before the run's frames were taken"
    if mode == "External":
        return f"{text}: the External triggers are not arriving"
    return text


class DetectorManagerPart(Part):
    """Scans an areaDetector: driver, position plugin and HDF5 writer."""

    def __init__(
        self,
        name: str,
        driver: str,
        plugin: str,
        writer: str,
        trigger_mode: str = "Internal",
        format_name: str = "",
        preload: int = 10000,
    ) -> None:
        super().__init__(name)
        if trigger_mode not in TRIGGER_MODES:
            raise ValueError(
                f"trigger_mode must be one of {', '.join(TRIGGER_MODES)},"
                f" not {trigger_mode!r}"
            )
        if int(preload) < 1:
            raise ValueError(f"preload must be at least 1, not {preload}")
        self.mris = {"driver": driver, "plugin": plugin, "writer": writer}
        self.initial_trigger_mode = trigger_mode
        self.format_name = format_name
        self.preload = int(preload)
        self._mri = ""
        self._origin: str | None = None
        self._process: Any = None
        self._armed = False
        #: the busy puts in flight: child key -> future
        self._busy: dict[str, Any] = {}
        self._loaded = 0  # positions loaded into the plugin (point index)
        self._end = 0  # where the armed run stops
        self._topping = False
        self._file = ""
        self._mode = ""  # the trigger mode of the scan configured
        self._frame_timeout = 0.0  # seconds without a frame = Fault

    # ---- fields
    def setup(self, registrar: PartRegistrar) -> None:
        self._mri = registrar.mri
        self._controller = registrar.controller
        default_name = self.format_name or self._mri.split(":")[-1].lower()
        registrar.add_configure_arg(
            "fileDir",
            StringMeta("Directory of the raw file ('' for no file)"),
            default="",
        )
        registrar.add_configure_arg(
            "formatName",
            StringMeta("The file is <fileDir>/<formatName>.h5"),
            default=default_name,
        )
        registrar.add_configure_arg(
            "exposure",
            NumberMeta("float64", "Exposure per frame in s (0: the scan's duration)"),
            default=0.0,
        )
        registrar.add_configure_arg(
            "frameTimeout",
            NumberMeta(
                "float64",
                "Seconds without a new frame before the run faults"
                f" (0: {FRAME_TIMEOUT_FACTOR:g} x the longest point"
                f" + {FRAME_TIMEOUT_MARGIN:g} s)",
            ),
            default=0.0,
        )
        self.trigger_mode = registrar.add_attribute(
            "triggerMode",
            ChoiceMeta(
                TRIGGER_MODES,
                "Internal: frames at the exposure; External: a"
                " frame per trigger (armed at configure)",
            ),
            self.initial_trigger_mode,
            put=self._put_trigger_mode,
        )
        self.datasets = registrar.add_attribute("datasets", datasets_meta())

    async def _put_trigger_mode(self, value: str) -> None:
        self.trigger_mode.set_value(value)

    @property
    def external(self) -> bool:
        """Whether the scan configured (else the attribute) is External: a
        change of ``triggerMode`` applies from the next configure."""
        return (self._mode or self.trigger_mode.value) == "External"

    def _view(self, key: str) -> BlockView:
        process = self._controller.process
        return BlockView(process, self.mris[key], self._mri)

    @property
    def drv(self) -> BlockView:
        return self._view("driver")

    @property
    def pos(self) -> BlockView:
        return self._view("plugin")

    @property
    def hdf(self) -> BlockView:
        return self._view("writer")

    # ---- errors
    def _lost(self, task: Task) -> str:
        """The children whose health is not OK, each with its first problem."""
        bad = []
        for mri in self.mris.values():
            try:
                health = task.process.get([mri, "health", "value"])
            except LookupError:
                health = "no such block"
            if health != "OK":
                problems = str(health).split("; ")
                more = f" and {len(problems) - 1} more" if len(problems) > 1 else ""
                bad.append(f"{mri} ({problems[0]}{more})")
        return ", ".join(bad)

    def _failed(self, task: Task, e: Exception) -> MalcolmError:
        lost = self._lost(task)
        return MalcolmError(f"{e}" + (f" (children not OK: {lost})" if lost else ""))

    # ---- parameters
    def _exposure(self, device: Any, step: int) -> float:
        exposure = float(device.params.get("exposure") or 0.0)
        if exposure <= 0 and device.points is not None:
            exposure = float(device.points.duration_at(step) or 0.0)
        return exposure

    @RunnableDevice.Validate
    async def validate(self, task: Task, device: Any) -> dict[str, Any]:
        file_dir = str(device.params.get("fileDir") or "")
        name = str(device.params.get("formatName") or "")
        if file_dir and not os.path.isabs(file_dir):
            raise BadValueError(
                f"{self._mri}.configure.fileDir: {file_dir!r} is not an absolute path"
            )
        check_file_args(self._mri, file_dir, name)
        if self.trigger_mode.value != "External":
            exposure = float(device.params.get("exposure") or 0.0)
            points = device.points
            duration = points.duration_at(0) if points is not None else None
            if exposure <= 0 and not duration:
                raise BadValueError(
                    f"{self._mri}.configure: Internal triggering needs the"
                    " scan's duration or an exposure"
                )
        return self._at_least_readout(device)

    def _at_least_readout(self, device: Any) -> dict[str, Any]:
        """The scan's duration (and ``exposure``) raised to
        :data:`MIN_EXPOSURE`, as a detector's readout time does: a
        CompoundGenerator structure comes back with its ``duration`` raised;
        another scan whose points are shorter is refused, naming the
        minimum."""
        tweaks: dict[str, Any] = {}
        exposure = float(device.params.get("exposure") or 0.0)
        if 0 < exposure < MIN_EXPOSURE:
            tweaks["exposure"] = MIN_EXPOSURE
        generator = device.params.get("generator")
        if isinstance(generator, dict) and "generators" in generator:
            if 0 < float(generator.get("duration", -1)) < MIN_EXPOSURE:
                tweaks["generator"] = {**generator, "duration": MIN_EXPOSURE}
            return tweaks
        points = device.points
        if points is None or not points.has_duration or not points.size:
            return tweaks
        shortest = float(points.duration.min())
        if shortest >= MIN_EXPOSURE:
            return tweaks
        raise BadValueError(
            f"{self._mri}.configure.generator: a point of {shortest:g} s is"
            f" shorter than the detector's shortest frame, {MIN_EXPOSURE:g} s"
        )

    # ---- configure
    @RunnableDevice.Configure
    async def configure(self, task: Task, device: Any) -> None:
        try:
            if self._armed or self._busy or self._children_busy():
                await self._stop_all(task)
            file_dir = str(device.params.get("fileDir") or "")
            name = str(device.params.get("formatName") or "")
            self._file = f"{name}.h5" if file_dir else ""
            self._mode = self.trigger_mode.value
            self._frame_timeout = self.frame_timeout(device)
            settings = self._settings(device, file_dir, name)
            self._show_datasets(name)
            await self._arm(task, 0, device.configuredSteps, True, settings)
        except ChannelError as e:
            raise self._failed(task, e) from e

    @staticmethod
    def frame_timeout(device: Any) -> float:
        """Seconds a run waits for its next frame: ``frameTimeout``,
        else :data:`FRAME_TIMEOUT_FACTOR` x the scan's longest point +
        :data:`FRAME_TIMEOUT_MARGIN`."""
        given = float(device.params.get("frameTimeout") or 0.0)
        if given > 0:
            return given
        points = device.points
        longest = 0.0
        if points is not None and points.has_duration and points.size:
            longest = float(points.duration.max())
        return FRAME_TIMEOUT_FACTOR * longest + FRAME_TIMEOUT_MARGIN

    def _children_busy(self) -> bool:
        """Whether the driver acquires, the plugin runs or the writer
        captures (left so by someone else, or by a scan that faulted)."""
        return bool(
            self.drv.detectorState.value != "Idle"
            or self.pos.running.value
            or self.hdf.capture.value
        )

    def _settings(self, device: Any, file_dir: str, name: str) -> dict[Any, Any]:
        """The driver's and writer's settings for the scan."""
        drv, hdf = self.drv, self.hdf
        exposure = max(self._exposure(device, 0), MIN_EXPOSURE)
        puts = {
            drv.exposure: exposure,
            drv.acquirePeriod: exposure,
            drv.imageMode: "Multiple",
            drv.triggerMode: self._mode,
            drv.arrayCallbacks: True,
            hdf.enableCallbacks: bool(file_dir),
        }
        if file_dir:
            puts.update(
                {
                    hdf.filePath: file_dir.rstrip("/") + "/",
                    hdf.fileName: name,
                    hdf.fileTemplate: "%s%s.h5",
                }
            )
        return puts

    @staticmethod
    def _changed(puts: dict[Any, Any]) -> dict[Any, Any]:
        """The settings the children do not hold already (each put is a CA
        round trip)."""
        changed = {}
        for view, value in puts.items():
            now = view.value
            if isinstance(value, float) and isinstance(now, float):
                same = abs(now - value) <= 1e-9 * max(1.0, abs(value))
            else:
                same = now == value
            if not same:
                changed[view] = value
        return changed

    def _show_datasets(self, name: str) -> None:
        rows = []
        if self._file:
            rows.append(
                {
                    "name": f"{name}.data",
                    "filename": self._file,
                    "type": "primary",
                    "rank": 2,
                    "path": DATA_PATH,
                    "uniqueid": UID_PATH,
                }
            )
        self.datasets.set_value(dataset_rows(rows))

    # ---- arming and stopping
    async def _load(self, task: Task, upto: int, *before: Any) -> None:
        """Load positions ``self._loaded .. upto-1`` into the plugin,
        ``XML_BATCH`` a put. The puts are all sent at once, in order: Channel
        Access delivers one client's puts to a record in the order sent and
        the record takes each after the last (a busy record queues the next
        put), so the plugin appends them in order while the next are on
        their way; each is still checked, after the puts ``before`` (sent
        before them: their errors first)."""
        puts = []
        while self._loaded < upto:
            start = self._loaded
            self._loaded = stop = min(upto, start + XML_BATCH)  # taken now
            puts.append(task.put_async(self.pos.xml, _batch_xml(start, stop)))
        await task.wait_all(*before, puts)

    async def _arm(
        self,
        task: Task,
        start: int,
        end: int,
        fresh: bool = False,
        settings: dict[Any, Any] | None = None,
    ) -> None:
        """Make the children wait for the frames of points ``start..end-1``:
        plugins first, then (External) the driver. A ``fresh`` file is made
        at once (so a bad fileDir shows now); otherwise the writer appends
        to the file, opening it at the first frame (so it stays closed while
        the scan is paused or between runs)."""
        self._armed = False
        self._busy = {}
        self._topping = False
        self._end = end
        frames = end - start
        if frames <= 0:
            return
        drv, pos, hdf = self.drv, self.pos, self.hdf
        puts = {
            **(settings or {}),
            drv.numImages: frames,
            pos.idStart: start + 1,
            pos.enableCallbacks: True,
        }
        if self._file:
            puts.update(
                {hdf.numCapture: frames, hdf.append: not fresh, hdf.lazyOpen: not fresh}
            )
        # Two chains at once: the writer's settings, then its capture (the
        # IOC makes the file); the plugin cleared, loaded, then started once
        # the other settings are in. A failure of either is raised (the other
        # chain's puts end by themselves, their errors retrieved by the task).
        changed = self._changed(puts)
        writer = self.mris["writer"] if self._file else None
        writer_puts = {v: x for v, x in changed.items() if v.mri == writer}
        other_puts = {v: x for v, x in changed.items() if v.mri != writer}
        chains = [asyncio.ensure_future(self._arm_plugin(task, start, end, other_puts))]
        if self._file:
            chains.append(asyncio.ensure_future(self._arm_writer(task, writer_puts)))
        try:
            await asyncio.gather(*chains)
        finally:  # one failed (or the arming was cancelled): the other ends too
            for chain in chains:
                chain.cancel()
            await asyncio.gather(*chains, return_exceptions=True)
        if self.external:
            self._busy["driver"] = task.put_async(drv.acquire, "Acquire")
            await self._until_armed(
                [
                    task.when_matches(
                        drv.detectorState, "Acquire", timeout=SETTLE_TIMEOUT
                    )
                ]
            )
        self._armed = True

    async def _arm_plugin(
        self, task: Task, start: int, end: int, settings: dict[Any, Any]
    ) -> None:
        """Clear and load the position plugin while ``settings`` go, then
        start it (once its positions and the driver's settings are in).
        The clearing and the positions are sent at once: the plugin takes
        one client's puts in the order sent (areaDetector's port thread, the
        simulation's dispatcher), so it clears before it loads, one round
        trip in a row where there were two."""
        pos = self.pos
        puts = task.put_async(settings)
        cleared = task.put_async(pos.delete, True)
        self._loaded = start
        await self._load(task, min(end, start + self.preload), cleared)
        await task.wait_all(puts)
        running = task.when_matches(pos.running, True, timeout=SETTLE_TIMEOUT)
        self._busy["plugin"] = task.put_async(pos.start, True)
        await self._until_armed([running])

    async def _arm_writer(self, task: Task, settings: dict[Any, Any]) -> None:
        """Set the writer up, then make it capture (the IOC opens the file)."""
        hdf = self.hdf
        await task.put(settings)
        capturing = task.when_matches(hdf.capture, True, timeout=SETTLE_TIMEOUT)
        self._busy["writer"] = task.put_async(hdf.capture, True)
        await self._until_armed([capturing])

    async def _until_armed(self, waits: list[Any]) -> None:
        """Wait for ``waits``; a busy put that ends first (it failed, or the
        writer could not open its file) fails the arming."""
        pending = set(waits)
        busy = set(self._busy.values())
        while pending:
            done, _ = await asyncio.wait(
                pending | busy, return_when=asyncio.FIRST_COMPLETED
            )
            for fut in done & busy:
                fut.result()  # its error, if it failed
                hdf = self.hdf
                if self._file and hdf.writeStatus.value != "Write OK":
                    raise MalcolmError(
                        f"{self.mris['writer']}: cannot write"
                        f" {hdf.fullFileName.value}: {hdf.writeMessage.value}"
                    )
                raise MalcolmError(f"{self._mri}: a child stopped while arming")
            for fut in done & pending:
                fut.result()
            pending -= done

    async def _stop_all(self, task: Task) -> None:
        """Stop the driver, then the plugins (the file is closed)."""
        armed = self._armed or bool(self._busy)
        self._armed = False
        self._busy = {}
        drv, pos, hdf = self.drv, self.pos, self.hdf
        await task.put(drv.stop, True)
        await task.wait_all(
            task.when_matches(drv.detectorState, "Idle", timeout=SETTLE_TIMEOUT)
        )
        if not (armed or pos.running.value or hdf.capture.value):
            return
        await task.put({pos.stop: True, hdf.stop: True})
        await task.wait_all(
            task.when_matches(pos.running, False, timeout=SETTLE_TIMEOUT),
            task.when_matches(hdf.capture, False, timeout=SETTLE_TIMEOUT),
        )

    # ---- run
    def _top_up(self, left: int, task: Task) -> Any:
        """Load more positions when the plugin runs low."""
        if self._topping or self._loaded >= self._end or left > XML_BATCH:
            return None
        self._topping = True  # now: the callback may come again before load runs

        async def load() -> None:
            try:
                await self._load(task, min(self._end, self._loaded + XML_BATCH))
            finally:
                self._topping = False

        return load()

    @RunnableDevice.Run
    async def run(self, task: Task, device: Any) -> None:
        start, end = int(device.completedSteps), int(device.configuredSteps)
        try:
            if not self._armed:
                await self._arm(task, start, end)
            if not self.external:
                self._busy["driver"] = task.put_async(self.drv.acquire, "Acquire")
            # the driver's and writer's puts end with the run's frames (the
            # plugin's ends when its positions are used up: not a frame count)
            busy = [self._busy[k] for k in ("driver", "writer") if k in self._busy]
            counter = self.hdf.numCaptured if self._file else self.pos.processed
            frames = FrameClock(start, self._made())

            def on_frames(n: Any) -> None:
                frames.saw(start + int(n))
                task.report_progress(min(start + int(n), end))

            ids = [
                task.subscribe(counter, on_frames),
                task.subscribe(self.pos.positions, self._top_up, task),
            ]
            try:
                await self._until_done_or_stalled(task, busy, frames)
            finally:
                for sid in ids:
                    task.unsubscribe(sid)
            if self.pos.running.value:
                await task.put(self.pos.stop, True)
        except ChannelError as e:
            raise self._failed(task, e) from e
        self._armed = False
        self._busy = {}
        if self._file and self.hdf.writeStatus.value != "Write OK":
            raise MalcolmError(
                f"{self.mris['writer']}: {self.hdf.writeMessage.value}"
                f" ({self.hdf.fullFileName.value})"
            )
        task.report_progress(end)

    def _made(self) -> int:
        """The driver's frame counter (its arrayCounter)."""
        try:
            return int(self.drv.arrayCounter.value)
        except (TypeError, ValueError):
            return 0

    async def _until_done_or_stalled(
        self, task: Task, busy: list[Any], frames: FrameClock
    ) -> None:
        """Wait for the run's ``busy`` puts; if no new frame comes within the
        frame timeout, stop the children and raise an error saying what is
        known (:func:`stall_message`)."""
        bound = self._frame_timeout or FRAME_TIMEOUT_MARGIN
        done = asyncio.ensure_future(task.wait_all(*busy))
        loop = asyncio.get_running_loop()
        try:
            while True:
                left = frames.since + bound - loop.time()
                if left <= 0:
                    break
                finished, _ = await asyncio.wait({done}, timeout=left)
                if finished:
                    done.result()
                    return
        finally:
            if not done.done():
                done.cancel()
        state = str(self.drv.detectorState.value)
        message = stall_message(
            self._mri,
            bound,
            frames,
            self._mode or self.trigger_mode.value,
            state,
            acquiring=state not in STOPPED_STATES,
            made=self._made() - frames.made,
            counted_by="the writer" if self._file else "the position plugin",
            callbacks=bool(self.drv.arrayCallbacks.value),
        )
        with contextlib.suppress(Exception):
            await self._stop_all(task)
        raise MalcolmError(message)

    @RunnableDevice.PostRunArmed
    async def post_run_armed(self, task: Task, device: Any) -> None:
        """Arm for the next run now, so an External detector waits for the
        motion's first trigger before the motion starts."""
        start, end = int(device.completedSteps), int(device.configuredSteps)
        try:
            await self._arm(task, start, end)
        except ChannelError as e:
            raise self._failed(task, e) from e

    # ---- pause, seek, abort, reset
    @RunnableDevice.Pause
    async def pause(self, task: Task, device: Any) -> None:
        try:
            await self._stop_all(task)
        except ChannelError as e:
            raise self._failed(task, e) from e

    @RunnableDevice.Seek
    async def seek(self, task: Task, device: Any) -> None:
        start, end = int(device.completedSteps), int(device.configuredSteps)
        try:
            await self._stop_all(task)
            await self._arm(task, start, end)
        except ChannelError as e:
            raise self._failed(task, e) from e

    @RunnableDevice.Abort
    async def abort(self, task: Task, device: Any) -> None:
        try:
            await self._stop_all(task)
        except ChannelError as e:
            raise self._failed(task, e) from e

    @RunnableDevice.Disable
    async def disable(self, task: Task, device: Any) -> None:
        """Let go of the hardware: stop it if it can be reached."""
        try:
            await self._stop_all(task)
        except ChannelError:
            pass  # unreachable hardware is not acquiring for us either

    @RunnableDevice.Reset
    async def reset(self, task: Task, device: Any) -> None:
        lost = self._lost(task)
        if lost:
            raise MalcolmError(f"hardware not connected: {lost}")
        try:
            await self._stop_all(task)
        except ChannelError as e:
            raise self._failed(task, e) from e

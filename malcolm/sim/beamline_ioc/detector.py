"""The simulated areaDetector: a driver, a position plugin and an HDF5 writer.

PVs (``P`` the IOC's prefix):

- driver ``P:CAM:``: ``Exposure``/``_RBV``, ``AcquirePeriod``/``_RBV``,
  ``NumImages``/``_RBV``, ``ImageMode``/``_RBV`` (Single, Multiple,
  Continuous), ``Acquire`` (Done/Acquire; a put of Acquire completes when
  the acquisition ends; Done stops it), ``Acquire_RBV``, ``ArrayCounter``/
  ``_RBV``, ``NumImagesCounter_RBV``, ``ArrayCallbacks``/``_RBV``,
  ``Manufacturer_RBV``, ``DetectorState_RBV``, ``Filename`` (a char
  waveform, the design document's ``xml``), ``MaxSize`` (frame side);
- position plugin ``P:POS:``: ``Delete``, ``IDStart``/``_RBV``,
  ``EnableCallbacks``/``_RBV``, ``Filename`` (XML of positions, appended to
  the buffer), ``Running`` (a put of 1 completes once the buffer is empty
  again; 0 stops), ``Running_RBV``, ``Qty`` (positions left), ``Index``
  (frames tagged);
- HDF5 writer ``P:HDF:``: ``FilePath``/``_RBV`` and ``FileName``/``_RBV``
  (char waveforms), ``FileTemplate``/``_RBV``, ``FullFileName_RBV``,
  ``NumCapture``/``_RBV``, ``NumCaptured_RBV``, ``Capture`` (a put of 1
  opens the file and completes when ``NumCapture`` frames are written),
  ``Capture_RBV``, ``WriteStatus`` (Write OK / Write error), ``WriteMessage``,
  ``EnableCallbacks``/``_RBV``.

Every frame the driver makes goes to the plugins whose callbacks are
enabled: the position plugin tags it with the next position, the writer
appends it (and its position) to the file with h5py.
"""

from __future__ import annotations

import asyncio
import xml.etree.ElementTree as ET
from collections import deque
from typing import Any

import numpy as np
from softioc import builder

TEXT = 65536  # bytes of a char waveform


def _stop_requested(record: Any) -> bool:
    """Whether a put of 0 reached ``record`` while its put is in progress
    (the IOC writes the field now and processes it after)."""
    try:
        return str(record.get_field("VAL")) in ("0", "Done", "Stop")
    except Exception:
        return False


def demand(
    name: str,
    make: Any,
    read_as: Any,
    initial: Any,
    rbv: dict[str, Any] | None = None,
    **fields: Any,
) -> Any:
    """An output record ``name`` whose puts its readback ``name_RBV`` shows
    (``rbv``: the readback's fields)."""
    readback = read_as(f"{name}_RBV", initial_value=initial, **(rbv or {}))
    return make(
        name,
        initial_value=initial,
        always_update=True,
        blocking=True,  # the put completes once the readback shows it
        on_update=readback.set,
        **fields,
    ), readback


class PositionPlugin:
    """NDPosPlugin: positions loaded as XML tag frames in order."""

    def __init__(self, prefix: str) -> None:
        builder.SetDeviceName(f"{prefix}:POS")
        self.buffer: deque[dict[str, str]] = deque()
        self.qty = builder.longIn("Qty", initial_value=0)
        self.index = builder.longIn("Index", initial_value=0)
        self.id_start, _ = demand("IDStart", builder.longOut, builder.longIn, 1)
        self.callbacks, self.callbacks_rbv = demand(
            "EnableCallbacks",
            builder.boolOut,
            builder.boolIn,
            0,
            ZNAM="Disable",
            ONAM="Enable",
            rbv={"ZNAM": "Disable", "ONAM": "Enable"},
        )
        self.delete = builder.boolOut(
            "Delete",
            ZNAM="Done",
            ONAM="Delete",
            on_update=self._delete,
            always_update=True,  # every put of Delete clears
            blocking=True,
        )
        self.xml = builder.longStringOut(
            "Filename",
            length=TEXT,
            on_update=self._load,
            always_update=True,
            blocking=True,  # the put completes once the positions are loaded
        )
        self.running_rbv = builder.boolIn(
            "Running_RBV", ZNAM="Idle", ONAM="Running", initial_value=0
        )
        self.running = builder.boolOut(
            "Running",
            ZNAM="Idle",
            ONAM="Running",
            on_update=self._run,
            blocking=True,
            always_update=True,
        )
        self.emptied = asyncio.Event()

    def _delete(self, value: int) -> None:
        if value:
            self.buffer.clear()
            self.qty.set(0)
            self.index.set(0)

    def _load(self, text: str) -> None:
        try:
            root = ET.fromstring(text)
        except ET.ParseError:
            self.qty.set(len(self.buffer), severity=2, alarm=7)  # MAJOR, STATE
            return
        for position in root.iter("position"):
            self.buffer.append(dict(position.attrib))
        self.qty.set(len(self.buffer))

    async def _run(self, value: int) -> None:
        if not value:
            return
        self.running_rbv.set(1)
        self.emptied.clear()
        try:
            while self.buffer and not _stop_requested(self.running):
                try:
                    await asyncio.wait_for(self.emptied.wait(), 0.05)
                except TimeoutError:
                    pass
        finally:
            self.running_rbv.set(0)

    def tag(self) -> dict[str, str] | None:
        """The position of the next frame, if running with callbacks on."""
        if not (self.running_rbv.get() and self.callbacks.get() and self.buffer):
            return None
        position = self.buffer.popleft()
        self.qty.set(len(self.buffer))
        self.index.set(self.index.get() + 1)
        if not self.buffer:
            self.emptied.set()
        return position


class HDFWriter:
    """NDFileHDF5: frames (and their positions) into one HDF5 file."""

    def __init__(self, prefix: str) -> None:
        builder.SetDeviceName(f"{prefix}:HDF")
        text: dict[str, Any] = {"length": 1024, "rbv": {"length": 1024}}
        self.path, _ = demand(
            "FilePath", builder.longStringOut, builder.longStringIn, "/tmp/", **text
        )
        self.name, _ = demand(
            "FileName", builder.longStringOut, builder.longStringIn, "", **text
        )
        self.template, _ = demand(
            "FileTemplate", builder.stringOut, builder.stringIn, "%s%s.h5"
        )
        self.full_name = builder.longStringIn("FullFileName_RBV", length=1024)
        self.num_capture, _ = demand("NumCapture", builder.longOut, builder.longIn, 1)
        self.num_captured = builder.longIn("NumCaptured_RBV", initial_value=0)
        self.status = builder.mbbIn(
            "WriteStatus", "Write OK", "Write error", initial_value=0
        )
        self.message = builder.stringIn("WriteMessage", initial_value="")
        self.callbacks, _ = demand(
            "EnableCallbacks",
            builder.boolOut,
            builder.boolIn,
            0,
            ZNAM="Disable",
            ONAM="Enable",
            rbv={"ZNAM": "Disable", "ONAM": "Enable"},
        )
        self.capture_rbv = builder.boolIn(
            "Capture_RBV", ZNAM="Done", ONAM="Capturing", initial_value=0
        )
        self.capture = builder.boolOut(
            "Capture",
            ZNAM="Done",
            ONAM="Capture",
            on_update=self._capture,
            blocking=True,
            always_update=True,
        )
        self.file: Any = None
        self.done = asyncio.Event()

    def _fail(self, message: str) -> None:
        self.status.set(1)
        self.message.set(message[:39])

    async def _capture(self, value: int) -> None:
        if not value:
            return
        import h5py

        try:
            filename = self.template.get() % (self.path.get(), self.name.get())
        except (TypeError, ValueError) as e:
            self._fail(f"bad template: {e}")
            return
        self.full_name.set(filename)
        try:
            self.file = h5py.File(filename, "w")
        except OSError as e:
            self._fail(f"cannot open: {e.strerror or e}")
            return
        self.status.set(0)
        self.message.set("")
        self.num_captured.set(0)
        self.capture_rbv.set(1)
        self.done.clear()
        try:
            while not self.done.is_set() and not _stop_requested(self.capture):
                try:
                    await asyncio.wait_for(self.done.wait(), 0.05)
                except TimeoutError:
                    pass
        finally:
            file, self.file = self.file, None
            file.close()
            self.capture_rbv.set(0)

    def write(self, frame: np.ndarray, uid: int, position: dict | None) -> None:
        """Append ``frame`` if capturing with callbacks on."""
        file = self.file
        if file is None or not self.callbacks.get():
            return
        try:
            data = file.get("entry/data")
            if data is None:
                data = file.create_dataset(
                    "entry/data",
                    shape=(0, *frame.shape),
                    maxshape=(None, *frame.shape),
                    dtype=frame.dtype,
                    chunks=(1, *frame.shape),
                )
                file.create_dataset("entry/uid", (0,), maxshape=(None,), dtype="i4")
            n = data.shape[0]
            data.resize(n + 1, axis=0)
            data[n] = frame
            uids = file["entry/uid"]
            uids.resize(n + 1, axis=0)
            uids[n] = uid
            for key, text in (position or {}).items():
                name = f"entry/positions/{key}"
                values = file.get(name)
                if values is None:
                    values = file.create_dataset(
                        name, (0,), maxshape=(None,), dtype="f8"
                    )
                values.resize(n + 1, axis=0)
                values[n] = float(text)
            file.flush()
        except (OSError, ValueError) as e:
            self._fail(f"write failed: {e}")
            self.done.set()
            return
        self.num_captured.set(n + 1)
        wanted = self.num_capture.get()
        if wanted and n + 1 >= wanted:
            self.done.set()


class Detector:
    """A simulated detector driver feeding its plugins."""

    def __init__(self, prefix: str, plugins: list[Any]) -> None:
        self.plugins = plugins
        builder.SetDeviceName(f"{prefix}:CAM")
        seconds = {"EGU": "s", "PREC": 4, "DRVL": 0.0, "DRVH": 100.0}
        self.exposure, _ = demand(
            "Exposure",
            builder.aOut,
            builder.aIn,
            0.1,
            **seconds,
            rbv={"EGU": "s", "PREC": 4},
        )
        self.period, _ = demand(
            "AcquirePeriod",
            builder.aOut,
            builder.aIn,
            0.1,
            **seconds,
            rbv={"EGU": "s", "PREC": 4},
        )
        self.num_images, _ = demand(
            "NumImages", builder.longOut, builder.longIn, 1, DRVL=1, DRVH=1000000
        )
        modes = ("Single", "Multiple", "Continuous")
        self.mode, _ = self._modes(modes)
        self.counter, self.counter_rbv = demand(
            "ArrayCounter", builder.longOut, builder.longIn, 0
        )
        self.images = builder.longIn("NumImagesCounter_RBV", initial_value=0)
        self.callbacks, _ = demand(
            "ArrayCallbacks",
            builder.boolOut,
            builder.boolIn,
            1,
            ZNAM="Disable",
            ONAM="Enable",
            rbv={"ZNAM": "Disable", "ONAM": "Enable"},
        )
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

    def _modes(self, modes: tuple[str, ...]) -> tuple[Any, Any]:
        readback = builder.mbbIn("ImageMode_RBV", *modes, initial_value=0)
        mode = builder.mbbOut(
            "ImageMode",
            *modes,
            initial_value=0,
            always_update=True,
            blocking=True,
            on_update=readback.set,
        )
        return mode, readback

    async def _acquire(self, value: int) -> None:
        if not value:
            return
        mode = self.mode.get()
        total = 1 if mode == 0 else self.num_images.get() if mode == 1 else None
        self.acquire_rbv.set(1)
        self.state.set(1)
        self.images.set(0)
        loop = asyncio.get_running_loop()
        deadline = loop.time()
        made = 0
        try:
            while total is None or made < total:
                deadline += max(self.exposure.get(), self.period.get(), 0.0005)
                await asyncio.sleep(max(0.0, deadline - loop.time()))
                if _stop_requested(self.acquire):
                    break
                made += 1
                self._frame(made)
        finally:
            self.state.set(0)
            self.acquire_rbv.set(0)

    def _frame(self, made: int) -> None:
        uid = self.counter_rbv.get() + 1
        self.counter_rbv.set(uid)
        self.images.set(made)
        side = int(self.size.get())
        frame = np.full((side, side), uid % 65536, dtype=np.uint16)
        if not self.callbacks.get():
            return
        position = None
        for plugin in self.plugins:
            if isinstance(plugin, PositionPlugin):
                position = plugin.tag()
            elif isinstance(plugin, HDFWriter):
                plugin.write(frame, uid, position)


def make_detector(prefix: str) -> Detector:
    """The driver and its two plugins, under ``prefix``."""
    plugins: list[Any] = [PositionPlugin(prefix), HDFWriter(prefix)]
    return Detector(prefix, plugins)

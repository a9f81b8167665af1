"""The simulated areaDetector plugins: a position plugin and an HDF5 writer.

PVs (``P`` the IOC's prefix):

- position plugin ``P:POS:``: ``Delete``, ``IDStart``/``_RBV``,
  ``EnableCallbacks``/``_RBV``, ``Filename`` (XML of positions, appended to
  the buffer), ``Running`` (a put of 1 completes once the buffer is empty
  again; 0 stops), ``Running_RBV``, ``Qty`` (positions left), ``Index``
  (frames tagged since the last ``Delete``), ``Stop`` (a put of 1 ends a
  ``Running`` put at once; not in areaDetector, see below). A tagged frame's
  uniqueId becomes ``IDStart + Index`` (before the count goes up), as
  NDPosPlugin does with no ``IDName``;
- HDF5 writer ``P:HDF:``: ``FilePath``/``_RBV`` and ``FileName``/``_RBV``
  (char waveforms), ``FileTemplate``/``_RBV``, ``FullFileName_RBV``,
  ``NumCapture``/``_RBV`` (0: no limit; read at every frame), ``NumCaptured_RBV``,
  ``Capture`` (a put of 1 opens the file and completes when ``NumCapture``
  frames are written, or on a stop; the file is closed then), ``Capture_RBV``,
  ``WriteStatus`` (Write OK / Write error), ``WriteMessage``,
  ``EnableCallbacks``/``_RBV``, ``LazyOpen``/``_RBV`` (open the file at the
  first frame, as areaDetector's), ``Append``/``_RBV`` (not in areaDetector:
  a capture continues the file's datasets, so a scan re-armed after a pause
  writes the re-done frames after the others) and ``Stop``.

A busy record's put (``Running``, ``Capture``) holds a put-with-callback of 0
until it is done (docs/ca.md), so each has a ``Stop`` record a client can
put with completion to end it now.

The per-frame counters (``Qty``, ``Index``, ``NumCaptured_RBV``) are posted
at most every :data:`~.pace.STATUS_PERIOD` (:mod:`.pace`), as a status
poll would show them (areaDetector posts them per frame, and Channel Access
merges a subscription's updates when its client falls behind), and always
before the busy put that they count ends (and at once after a ``Delete`` or
a load of positions).
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import xml.etree.ElementTree as ET
from typing import Any

import numpy as np
from softioc import builder

from .dispatch import in_place
from .pace import Throttled
from .positions import PositionBuffer, parse_positions

TEXT = 65536  # bytes of a char waveform
FLUSH_ROWS = 200  # frames the writer keeps before writing them


def stop_requested(record: Any) -> bool:
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
        on_update=in_place(readback.set),  # no hop to the IOC's loop
        **fields,
    ), readback


def enable(name: str, initial: int = 0) -> tuple[Any, Any]:
    """An Enable/Disable demand with its readback."""
    labels = {"ZNAM": "Disable", "ONAM": "Enable"}
    return demand(name, builder.boolOut, builder.boolIn, initial, rbv=labels, **labels)


class Stoppable:
    """A busy record's ``Stop`` companion: ``stopping`` is set by a put of 1
    to ``Stop`` (or of 0 to the busy record) until the next start."""

    def __init__(self) -> None:
        self._stop = False
        builder.boolOut(
            "Stop",
            ZNAM="Done",
            ONAM="Stop",
            on_update=self._on_stop,
            always_update=True,
        )

    def _on_stop(self, value: int) -> None:
        if value:
            self._stop = True
            self.wake()

    def wake(self) -> None:
        """Wake the busy put's loop so that it sees the stop now."""

    def started(self) -> None:
        self._stop = False

    def stopping(self, record: Any) -> bool:
        return self._stop or stop_requested(record)


class PositionPlugin(Stoppable):
    """NDPosPlugin: positions loaded as XML tag frames in order."""

    def __init__(self, prefix: str) -> None:
        builder.SetDeviceName(f"{prefix}:POS")
        super().__init__()
        self.buffer = PositionBuffer()
        self.qty = Throttled(builder.longIn("Qty", initial_value=0))
        self.index = Throttled(builder.longIn("Index", initial_value=0))
        self.id_start, _ = demand("IDStart", builder.longOut, builder.longIn, 1)
        self.callbacks, self.callbacks_rbv = enable("EnableCallbacks")
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

    def wake(self) -> None:
        self.emptied.set()

    def _delete(self, value: int) -> None:
        if value:
            self.buffer.clear()
            self.qty.set(0)
            self.index.set(0)
            self.qty.flush()
            self.index.flush()

    def _load(self, text: str) -> None:
        try:
            parse_positions(text, self.buffer)
        except ET.ParseError:
            self.qty.set(len(self.buffer))
            self.qty.flush(severity=2, alarm=7)  # MAJOR, STATE
            return
        self.qty.set(len(self.buffer))
        self.qty.flush(severity=0, alarm=0)  # posted now, any alarm cleared

    async def _run(self, value: int) -> None:
        if not value:
            return
        self.started()
        self.running_rbv.set(1)
        self.emptied.clear()
        try:
            while self.buffer and not self.stopping(self.running):
                try:
                    await asyncio.wait_for(self.emptied.wait(), 0.05)
                except TimeoutError:
                    pass
        finally:
            self.qty.flush()
            self.index.flush()
            self.running_rbv.set(0)

    def tag(self) -> tuple[int, dict[str, str]] | None:
        """The uniqueId and position of the next frame, if running with
        callbacks on."""
        if not (self.running_rbv.get() and self.callbacks.get() and self.buffer):
            return None
        position = self.buffer.popleft()
        self.qty.set(len(self.buffer))
        index = self.index.get()
        self.index.set(index + 1)
        if not self.buffer:
            self.emptied.set()
        return int(self.id_start.get()) + index, position


class HDFWriter(Stoppable):
    """NDFileHDF5: frames (and their positions) into one HDF5 file."""

    def __init__(self, prefix: str) -> None:
        builder.SetDeviceName(f"{prefix}:HDF")
        super().__init__()
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
        self.num_captured = Throttled(
            builder.longIn("NumCaptured_RBV", initial_value=0)
        )
        self.status = builder.mbbIn(
            "WriteStatus", "Write OK", "Write error", initial_value=0
        )
        self.message = builder.stringIn("WriteMessage", initial_value="")
        self.callbacks, _ = enable("EnableCallbacks")
        yes_no = {"ZNAM": "No", "ONAM": "Yes"}
        self.lazy, _ = demand(
            "LazyOpen", builder.boolOut, builder.boolIn, 0, rbv=yes_no, **yes_no
        )
        self.append, _ = demand(
            "Append", builder.boolOut, builder.boolIn, 0, rbv=yes_no, **yes_no
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
        self.rows: list[tuple[np.ndarray, int, dict]] = []
        self.filename = ""
        self.capturing = False
        self.done = asyncio.Event()

    def wake(self) -> None:
        self.done.set()

    def _fail(self, message: str) -> None:
        self.status.set(1)
        self.message.set(message[:39])

    def _open(self) -> bool:
        import h5py

        mode = "a" if self.append.get() else "w"
        try:
            if mode == "w":
                # a file there is removed, not truncated by HDF5 (~3 ms a
                # file on the IOC's loop where this takes 0.3 ms)
                with contextlib.suppress(FileNotFoundError):
                    os.unlink(self.filename)
            self.file = h5py.File(self.filename, mode)
        except OSError as e:
            self._fail(f"cannot open: {e.strerror or e}")
            return False
        return True

    async def _capture(self, value: int) -> None:
        if not value:
            return
        self.started()
        try:
            self.filename = self.template.get() % (self.path.get(), self.name.get())
        except (TypeError, ValueError) as e:
            self._fail(f"bad template: {e}")
            return
        self.full_name.set(self.filename)
        self.status.set(0)
        self.message.set("")
        if not self.lazy.get() and not self._open():
            return
        self.num_captured.set(0)
        self.num_captured.flush()
        self.rows = []
        self.capturing = True
        self.capture_rbv.set(1)
        self.done.clear()
        try:
            while not self.done.is_set() and not self.stopping(self.capture):
                try:
                    await asyncio.wait_for(self.done.wait(), 0.05)
                except TimeoutError:
                    self._flush()
        finally:
            self.capturing = False
            self._flush()
            file, self.file = self.file, None
            if file is not None:
                file.close()
            self.num_captured.flush()
            self.capture_rbv.set(0)

    def write(self, frame: np.ndarray, uid: int, position: dict | None) -> None:
        """Take ``frame`` if capturing with callbacks on: it is written to the
        file with the frames after it (``FLUSH_ROWS`` at a time, at least
        every 50 ms, and when the capture ends)."""
        if not self.capturing or not self.callbacks.get() or self.done.is_set():
            return
        self.rows.append((frame, uid, position or {}))
        if len(self.rows) >= FLUSH_ROWS and not self._flush():
            return
        captured = self.num_captured.get() + 1
        self.num_captured.set(captured)
        wanted = self.num_capture.get()
        if wanted and captured >= wanted:
            self.done.set()

    def _flush(self) -> bool:
        """Write the frames taken so far; False (and a write error) if that
        failed, which ends the capture."""
        rows, self.rows = self.rows, []
        if not rows:
            return True
        if self.file is None and not self._open():
            self.done.set()
            return False
        try:
            append_rows(self.file, rows)
        except (OSError, ValueError, KeyError) as e:
            self._fail(f"write failed: {e}")
            self.done.set()
            return False
        return True


def append_rows(file: Any, rows: list[tuple[np.ndarray, int, dict]]) -> None:
    """Append frames, uniqueIds and positions to the file's datasets."""
    frames = np.stack([frame for frame, _, _ in rows])
    shape = frames.shape[1:]
    data = file.get("entry/data")
    if data is None:
        per_chunk = max(1, min(256, 65536 // max(1, frames[0].nbytes)))
        data = file.create_dataset(
            "entry/data",
            shape=(0, *shape),
            maxshape=(None, *shape),
            dtype=frames.dtype,
            chunks=(per_chunk, *shape),
        )
        file.create_dataset("entry/uid", (0,), maxshape=(None,), dtype="i4")
    n, k = data.shape[0], len(rows)
    data.resize(n + k, axis=0)
    data[n:] = frames
    uids = file["entry/uid"]
    uids.resize(n + k, axis=0)
    uids[n:] = [uid for _, uid, _ in rows]
    keys = sorted({key for _, _, position in rows for key in position})
    for key in keys:
        name = f"entry/positions/{key}"
        values = file.get(name)
        if values is None:
            values = file.create_dataset(name, (0,), maxshape=(None,), dtype="f8")
        column = [float(p.get(key, "nan")) for _, _, p in rows]
        old = values.shape[0]
        values.resize(n + k, axis=0)
        if old < n:  # a key first seen now: earlier rows have none
            values[old:n] = np.nan
        values[n:] = column

"""PCAP samples into an HDF5 file (h5py), one dataset per captured column.

:func:`capture_to_file` streams one experiment from a
:class:`~malcolm.io.zebra2.data.DataClient` into a file and returns the
rows written and the ``END``. :class:`CaptureFile` is made from the data
port header (``StartData``): a
1-D dataset per column named ``<FIELD>.<CAPTURE>`` (``COUNTER2.OUT.Min``),
chunked and growing, with attributes ``capture``, ``units``, ``scale``,
``offset`` (as the header gives them) and ``type`` (the box's type). Its
methods are plain blocking calls: run them in a worker thread
(``asyncio.to_thread``), never on the loop.
"""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any

import h5py
import numpy as np
from pandablocks.responses import EndData, FrameData, StartData

__all__ = ["CaptureFile", "capture_to_file"]

#: rows per HDF5 chunk
CHUNK_ROWS = 16384


class CaptureFile:
    """An open HDF5 file taking one experiment's frames."""

    def __init__(self, path: str | Path, start: StartData, append: bool = False):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.rows = 0
        self.names: list[str] = []
        self.datasets: list[h5py.Dataset] = []
        if append and self.path.exists():
            self._append(start)
            return
        self.file = h5py.File(self.path, "w", libver="latest")
        self.file.attrs["arm_time"] = str(start.arm_time or "")
        self.file.attrs["start_time"] = str(start.start_time or "")
        self.file.attrs["process"] = str(start.process)
        self.file.attrs["missed"] = int(start.missed)
        for f in start.fields:
            name = f"{f.name}.{f.capture}"
            ds = self.file.create_dataset(
                name,
                shape=(0,),
                maxshape=(None,),
                dtype=f.type,
                chunks=(CHUNK_ROWS,),
            )
            ds.attrs["capture"] = f.capture
            ds.attrs["type"] = str(f.type)
            if f.units is not None:
                ds.attrs["units"] = f.units
            if f.scale is not None:
                ds.attrs["scale"] = f.scale
            if f.offset is not None:
                ds.attrs["offset"] = f.offset
            self.names.append(name)
            self.datasets.append(ds)

    def _append(self, start: StartData) -> None:
        """Go on with the file of an earlier experiment of the same fields
        (the next run of a scan)."""
        self.file = h5py.File(self.path, "a")
        names = [f"{f.name}.{f.capture}" for f in start.fields]
        missing = [n for n in names if n not in self.file]
        if missing:
            self.file.close()
            raise ValueError(
                f"{self.path}: cannot append: it has no dataset {missing[0]}"
            )
        self.names = names
        self.datasets = [self.file[n] for n in names]
        self.rows = len(self.datasets[0]) if self.datasets else 0

    def write(self, frames: np.ndarray) -> int:
        """Append a structured array of samples; the rows written so far."""
        n = len(frames)
        if n:
            end = self.rows + n
            for name, ds in zip(frames.dtype.names or (), self.datasets):
                ds.resize((end,))
                ds[self.rows : end] = frames[name]
            self.rows = end
        return self.rows

    def close(self, samples: int | None = None, reason: str = "") -> None:
        """Close; ``samples``/``reason`` from the (last) END line become
        attributes."""
        if self.file.id.valid:
            if samples is not None:
                self.file.attrs["end_samples"] = int(samples)
            self.file.attrs["end_reason"] = reason
            self.file.close()


async def capture_to_file(
    data: Any,
    path: str | Path,
    on_rows: Callable[[int], Awaitable[None] | None] | None = None,
    append: bool = False,
) -> tuple[int, EndData | None]:
    """Write the next experiment of ``data`` (a connected DataClient) into
    ``path``: (rows of this experiment written, its EndData). The file is
    made at the header (``append``: an existing file's datasets grow), each
    chunk of frames is written in a worker thread (never on the loop), and
    ``on_rows(rows)`` is called after each (it may be async)."""
    file: CaptureFile | None = None
    rows = first = 0
    end: EndData | None = None
    try:
        async for item in data.experiment():
            if isinstance(item, StartData):
                file = await asyncio.to_thread(CaptureFile, path, item, append)
                first = file.rows
            elif isinstance(item, FrameData) and file is not None:
                rows = await asyncio.to_thread(file.write, item.data) - first
                if on_rows is not None:
                    result = on_rows(rows)
                    if result is not None:
                        await result
            elif isinstance(item, EndData):
                end = item
                if file is not None:
                    await asyncio.to_thread(file.close, end.samples, end.reason.value)
    finally:
        if file is not None:
            await asyncio.to_thread(file.close)
    return rows, end

"""The ZebraManager's raw file and its ``datasets`` table.

One HDF5 file per scan, ``<fileDir>/<formatName>.h5``: a 1-d dataset per
captured column (``/COUNTER1.OUT.Value``, ``/PCAP.TS_TRIG.Value``, as
:class:`~malcolm.io.zebra2.hdf.CaptureFile` names them) and ``/uniqueid``
(int32: the point of each row + 1), one row per PCAP sample in the order
the box sent them. :func:`create_scan_file` makes it empty at configure;
:class:`ScanFile` appends one experiment's frames to it and is closed at the
experiment's ``END``, so another process can read it whenever no
experiment is in progress. Every call is blocking: run it in a worker
thread. (h5py and numpy: imported when a scan is first configured.)
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from malcolm.io.zebra2.hdf import CHUNK_ROWS, CaptureFile

from .datasets import new_h5_file
from .zebra2_scan_datasets import COLUMNS, POSITION, UNIQUEID

__all__ = ["ScanFile", "create_scan_file", "uniqueids"]


def _dataset(f: h5py.File, name: str, dtype: Any) -> h5py.Dataset:
    return f.create_dataset(
        name, shape=(0,), maxshape=(None,), dtype=dtype, chunks=(CHUNK_ROWS,)
    )


def create_scan_file(path: str | Path, meta: dict[str, Any]) -> None:
    """An empty scan file at ``path`` (replacing one there), attributes
    ``meta``, ready for :class:`ScanFile` to append to."""
    with new_h5_file(path, libver="latest") as f:
        for k, v in meta.items():
            f.attrs[k] = v
        for column in COLUMNS:
            _dataset(f, column, np.float64).attrs["capture"] = "Value"
        ds = _dataset(f, UNIQUEID, np.int32)
        ds.attrs["description"] = "point index + 1 of each row"


class ScanFile(CaptureFile):
    """The scan file opened to append an experiment: its frames and, for
    each row, ``uniqueid`` = the row's position (the point index) + 1."""

    def __init__(self, path: str | Path, start: Any) -> None:
        super().__init__(path, start, append=True)
        self.uniqueid = self.file[UNIQUEID]
        #: rows in the file before this experiment
        self.first = self.rows
        #: the last row's uniqueid
        self.last_uid = 0

    def write(self, frames: np.ndarray) -> int:
        first = self.rows
        rows = super().write(frames)
        if rows > first:
            uid = np.rint(frames[POSITION]).astype(np.int32) + 1
            self.uniqueid.resize((rows,))
            self.uniqueid[first:rows] = uid
            self.last_uid = int(uid[-1])
        return rows


def uniqueids(path: str | Path) -> Sequence[int]:
    """The ``uniqueid`` dataset of a scan file (for tests and tools)."""
    with h5py.File(path, "r") as f:
        return f[UNIQUEID][()].tolist()

"""The ZebraManager's raw file and its ``datasets`` table.

One HDF5 file per scan, ``<fileDir>/<formatName>.h5``: a 1-d dataset per
captured column (``/COUNTER1.OUT.Value``, ``/PCAP.TS_TRIG.Value``, as
:class:`~malcolm.io.zebra2.hdf.CaptureFile` names them) and ``/uniqueid``
(int32: the point of each row + 1), one row per PCAP sample in the order
the box sent them. :func:`create_scan_file` makes it empty at configure;
:class:`ScanFile` appends one experiment's frames to it and is closed at the
experiment's ``END``, so another process can read it whenever no
experiment is in progress. Every call is blocking: run it in a worker
thread.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from malcolm.core import (
    ChoiceArrayMeta,
    NumberArrayMeta,
    StringArrayMeta,
    TableMeta,
)
from malcolm.io.zebra2.hdf import CHUNK_ROWS, CaptureFile

__all__ = [
    "DATASET_TYPES",
    "POSITION",
    "TIMESTAMP",
    "UNIQUEID",
    "ScanFile",
    "create_scan_file",
    "dataset_rows",
    "datasets_meta",
]

#: the box's column whose scaled value is the point's index (the simulated
#: encoder; docs/devices.md) and the trigger timestamp column
POSITION = "COUNTER1.OUT.Value"
TIMESTAMP = "PCAP.TS_TRIG.Value"
#: the columns the manager captures, in the box's capture order
COLUMNS = (POSITION, TIMESTAMP)
#: the dataset of each row's point + 1
UNIQUEID = "uniqueid"
DATASET_TYPES = ("primary", "secondary", "monitor", "position_set", "position_value")


def datasets_meta() -> TableMeta:
    """The ``datasets`` table GDA reads (pymalcolm's columns)."""
    return TableMeta(
        {
            "name": StringArrayMeta("Dataset name, e.g. zebra.COUNTER1.OUT"),
            "filename": StringArrayMeta("File it is in, relative to fileDir"),
            "type": ChoiceArrayMeta(DATASET_TYPES, "What the dataset holds"),
            "rank": NumberArrayMeta("int32", "Dimensions of one point's value"),
            "path": StringArrayMeta("HDF5 path of the dataset"),
            "uniqueid": StringArrayMeta("HDF5 path of each row's point + 1"),
        },
        "Datasets the last configure writes",
    )


def dataset_rows(prefix: str, filename: str) -> dict[str, list[Any]]:
    """The ``datasets`` columns for a file ``filename`` ("" = none)."""
    if not filename:
        return {k: [] for k in ("name", "filename", "type", "rank", "path", "uniqueid")}
    names = [f"{prefix}.{c.rsplit('.', 1)[0]}" for c in COLUMNS]
    return {
        "name": names,
        "filename": [filename] * len(COLUMNS),
        "type": ["monitor"] * len(COLUMNS),
        "rank": [0] * len(COLUMNS),
        "path": [f"/{c}" for c in COLUMNS],
        "uniqueid": [f"/{UNIQUEID}"] * len(COLUMNS),
    }


def _dataset(f: h5py.File, name: str, dtype: Any) -> h5py.Dataset:
    return f.create_dataset(
        name, shape=(0,), maxshape=(None,), dtype=dtype, chunks=(CHUNK_ROWS,)
    )


def create_scan_file(path: str | Path, meta: dict[str, Any]) -> None:
    """An empty scan file at ``path`` (replacing one there), attributes
    ``meta``, ready for :class:`ScanFile` to append to."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with h5py.File(path, "w", libver="latest") as f:
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

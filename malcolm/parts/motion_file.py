"""The motion controller's raw file: demand and readback per point reached.

``<fileDir>/<formatName>.h5`` holds, for each scan axis the controller
moves, ``/entry/<axis>/value_set`` (the point's demanded position) and
``/entry/<axis>/value`` (the motor readback when the trajectory reached the
point's midpoint), and ``/entry/uniqueid`` (point index + 1): 1-d datasets,
one row per point reached, in the order the hardware reached them (after a
pause and a seek back, re-done points appear again later with the same
uniqueid). The file is opened only while rows are appended (in a worker
thread, never on the loop), so another process can read it between runs.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from .datasets import datasets_meta, new_h5_file

if TYPE_CHECKING:
    import numpy as np

__all__ = ["MotionFile", "datasets_meta", "datasets_rows"]

UNIQUEID = "/entry/uniqueid"
#: rows per chunk of each dataset (what h5py guessed for them before)
CHUNK_ROWS = 1024


def value_path(axis: str, kind: str) -> str:
    return f"/entry/{axis}/{kind}"


def datasets_rows(filename: str, axes: Sequence[str]) -> dict[str, list[Any]]:
    """The ``datasets`` value for a file of ``axes`` (empty without a file)."""
    rows: dict[str, list[Any]] = {
        k: [] for k in ("name", "filename", "type", "rank", "path", "uniqueid")
    }
    if not filename:
        return rows
    for axis in axes:
        for kind, type_ in (("value_set", "position_set"), ("value", "position_value")):
            rows["name"].append(f"{axis}.{kind}")
            rows["filename"].append(filename)
            rows["type"].append(type_)
            rows["rank"].append(0)
            rows["path"].append(value_path(axis, kind))
            rows["uniqueid"].append(UNIQUEID)
    return rows


class MotionFile:
    """Appends rows of ``(uniqueid, demands, readbacks)`` to the HDF5 file."""

    def __init__(self, path: str, axes: Sequence[str]) -> None:
        self.path = path
        self.axes = list(axes)

    def create(self) -> None:
        """A new, empty file (blocking: call in a worker thread). Its groups
        are made one by one and its chunks given (h5py's path walk and
        chunk guess were half the cost of making it)."""
        with new_h5_file(self.path) as f:
            entry = f.create_group("entry")
            entry.create_dataset(
                "uniqueid", (0,), "int32", maxshape=(None,), chunks=(CHUNK_ROWS,)
            )
            for axis in self.axes:
                group = entry.create_group(axis)
                for kind in ("value_set", "value"):
                    group.create_dataset(
                        kind, (0,), "float64", maxshape=(None,), chunks=(CHUNK_ROWS,)
                    )

    def append(
        self,
        uniqueid: np.ndarray,
        demands: dict[str, np.ndarray],
        readbacks: dict[str, np.ndarray],
    ) -> None:
        """Add rows (blocking: call in a worker thread)."""
        import h5py

        n = len(uniqueid)
        if n == 0:
            return
        with h5py.File(self.path, "a") as f:
            columns = [(UNIQUEID, uniqueid)]
            for axis in self.axes:
                columns.append((value_path(axis, "value_set"), demands[axis]))
                columns.append((value_path(axis, "value"), readbacks[axis]))
            for path, values in columns:
                ds = f[path]
                old = ds.shape[0]
                ds.resize((old + n,))
                ds[old:] = values

"""One NeXus-style HDF5 file per scan, assembled from the devices' raw files.

A device manager describes what it wrote in its ``datasets`` table (the
contract of issue 13): rows of ``name`` (``det.data``, ``x.value_set``,
``panda.INENC1.VAL``), ``filename`` (relative to the scan's ``fileDir``),
``type`` (``primary``, ``secondary``, ``monitor``, ``position_set``,
``position_value``), ``rank`` (dimensions of one point's value), ``path``
(the HDF5 dataset) and ``uniqueid`` (a 1-d dataset of the same length giving
each row's point: index + 1, 0 = not a scan point).

:func:`assemble` reads them and writes one file:

- ``/entry`` (``NXentry``), ``/entry/instrument`` (``NXinstrument``, a link
  to each device group);
- one group per name prefix (``det``, ``x``, ``panda``), holding its
  datasets under the rest of the name (``/entry/det/data``,
  ``/entry/x/value_set``, ``/entry/panda/INENC1.VAL``); a group with a
  ``primary`` dataset is ``NXdata`` (``signal`` attribute, and links to the
  axes' demand positions), a group of positions ``NXpositioner``, any other
  ``NXcollection``;
- each dataset shaped ``scan shape + value shape``: of the rows with the
  same uniqueId the **last** one is kept (a seek back re-does points; the
  later row wins) and placed at point ``uniqueId - 1``; a point with no row
  holds NaN (floats) or 0;
- demand positions from the scan's points where no device gave them
  (``/entry/<axis>/value_set``);
- ``/entry/uniqueid``: ``index + 1`` where the primary datasets (else any)
  have a row, 0 elsewhere;
- a row that cannot be read (a raw file missing, unreadable or cut short
  by a lost IOC) is left out and named in ``/entry``'s ``problems``
  attribute (a list of strings), as in the result's ``problems``.

Reading is done with h5py in the caller's thread: call it from a worker
thread (``asyncio.to_thread``), never on the loop. The file is written to a
temporary name and renamed, so a reader never sees half a file.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "DATASET_TYPES",
    "AssembleResult",
    "DatasetRow",
    "assemble",
    "last_rows",
    "rows_from_table",
]

#: the ``type`` column's values
DATASET_TYPES = ("primary", "secondary", "monitor", "position_set", "position_value")

_NX_CLASS = "NX_class"


@dataclass(frozen=True)
class DatasetRow:
    """One row of a device's ``datasets`` table."""

    name: str
    filename: str
    type: str
    rank: int
    path: str
    uniqueid: str

    @property
    def group(self) -> str:
        """The file's group: the name before the first dot."""
        return self.name.split(".", 1)[0]

    @property
    def leaf(self) -> str:
        """The dataset's name in its group: the rest of the name."""
        parts = self.name.split(".", 1)
        return parts[1] if len(parts) > 1 else "data"


@dataclass
class AssembleResult:
    """What :func:`assemble` wrote, and what it could not."""

    path: Path
    #: the assembled file's own ``datasets`` rows (paths in the .nxs)
    rows: list[DatasetRow] = field(default_factory=list)
    #: per assembled dataset, the points it has a row for
    points_present: dict[str, int] = field(default_factory=dict)
    #: problems, each naming the row and file (the rest was written)
    problems: list[str] = field(default_factory=list)


def rows_from_table(table: Mapping[str, Sequence[Any]]) -> list[DatasetRow]:
    """A ``datasets`` table value (column-major) as rows; a table missing
    a column raises ValueError naming it."""
    columns = ("name", "filename", "type", "rank", "path", "uniqueid")
    for c in columns:
        if c not in table:
            raise ValueError(f"datasets table has no {c!r} column")
    n = len(table["name"])
    return [
        DatasetRow(
            name=str(table["name"][i]),
            filename=str(table["filename"][i]),
            type=str(table["type"][i]),
            rank=int(table["rank"][i]),
            path=str(table["path"][i]),
            uniqueid=str(table["uniqueid"][i]),
        )
        for i in range(n)
    ]


def last_rows(uids: np.ndarray, npoints: int) -> tuple[np.ndarray, np.ndarray]:
    """For uniqueIds ``uids`` (in file order), the row to keep for each
    point: ``(rows, points)``, the last row of each uniqueId in
    ``1..npoints`` and its point index (``uniqueId - 1``), ascending."""
    uids = np.asarray(uids).reshape(-1).astype(np.int64, copy=False)
    reversed_uids = uids[::-1]
    unique, first_in_reversed = np.unique(reversed_uids, return_index=True)
    rows = len(uids) - 1 - first_in_reversed
    keep = (unique >= 1) & (unique <= npoints)
    return rows[keep], unique[keep] - 1


def _fill_value(dtype: np.dtype) -> Any:
    return np.nan if np.issubdtype(dtype, np.floating) else 0


def _read_row(
    file_dir: Path, row: DatasetRow, npoints: int, h5py: Any
) -> tuple[np.ndarray, np.ndarray]:
    """The row's dataset as ``(values per point, mask of points present)``."""
    where = file_dir / row.filename
    with h5py.File(where, "r") as f:
        if row.path not in f:
            raise LookupError(f"{where} has no dataset {row.path!r}")
        if row.uniqueid not in f:
            raise LookupError(f"{where} has no uniqueid dataset {row.uniqueid!r}")
        data = f[row.path]
        uids = np.asarray(f[row.uniqueid][()]).reshape(-1)
        if data.shape[:1] != uids.shape[:1]:
            raise ValueError(
                f"{where}: {row.path} has {data.shape[0] if data.shape else 0}"
                f" rows but {row.uniqueid} has {len(uids)}"
            )
        rows, points = last_rows(uids, npoints)
        out = np.full((npoints, *data.shape[1:]), _fill_value(data.dtype), data.dtype)
        if len(rows):
            # one read of the whole dataset: h5py's reads of scattered rows
            # are far slower than numpy's indexing of what it read
            out[points] = np.asarray(data[()])[rows]
    mask = np.zeros(npoints, bool)
    mask[points] = True
    return out, mask


def assemble(
    out_path: str | os.PathLike[str],
    file_dir: str | os.PathLike[str],
    rows: Sequence[DatasetRow],
    shape: Sequence[int],
    demands: Mapping[str, np.ndarray] | None = None,
    attrs: Mapping[str, Any] | None = None,
) -> AssembleResult:
    """Write the scan's file ``out_path`` from the devices' ``rows`` (files
    relative to ``file_dir``) for a scan of ``shape``; ``demands`` (axis ->
    every point's demand position) fills ``/entry/<axis>/value_set`` where
    no device gave it; ``attrs`` go on ``/entry``. A row whose file or
    dataset cannot be read is left out and named in ``problems``."""
    import h5py

    out = Path(out_path)
    base = Path(file_dir)
    shape = tuple(int(s) for s in shape)
    npoints = int(np.prod(shape)) if shape else 1
    result = AssembleResult(out)
    tmp = out.with_name(f".{out.name}.{os.getpid()}.tmp")
    present_primary = np.zeros(npoints, bool)
    present_any = np.zeros(npoints, bool)
    groups: dict[str, dict[str, str]] = {}  # group -> leaf -> type
    try:
        with h5py.File(tmp, "w") as f:
            entry = f.create_group("entry")
            entry.attrs[_NX_CLASS] = "NXentry"
            for k, v in (attrs or {}).items():
                entry.attrs[k] = v
            for row in rows:
                try:
                    values, mask = _read_row(base, row, npoints, h5py)
                except Exception as e:  # one bad row must not lose the others
                    result.problems.append(f"{row.name} ({row.filename}): {e}")
                    continue
                group = entry.require_group(row.group)
                if row.leaf in group:
                    result.problems.append(f"{row.name}: named twice; first kept")
                    continue
                group.create_dataset(
                    row.leaf, data=values.reshape(shape + values.shape[1:])
                )
                groups.setdefault(row.group, {})[row.leaf] = row.type
                result.points_present[row.name] = int(mask.sum())
                present_any |= mask
                if row.type == "primary":
                    present_primary |= mask
                result.rows.append(
                    DatasetRow(
                        row.name,
                        out.name,
                        row.type,
                        row.rank,
                        f"/entry/{row.group}/{row.leaf}",
                        "/entry/uniqueid",
                    )
                )
            for axis, demand in (demands or {}).items():
                group = entry.require_group(axis)
                if "value_set" in group:
                    continue
                group.create_dataset(
                    "value_set", data=np.asarray(demand).reshape(shape)
                )
                groups.setdefault(axis, {})["value_set"] = "position_set"
                result.rows.append(
                    DatasetRow(
                        f"{axis}.value_set",
                        out.name,
                        "position_set",
                        0,
                        f"/entry/{axis}/value_set",
                        "/entry/uniqueid",
                    )
                )
            if result.problems:
                entry.attrs["problems"] = list(result.problems)
            present = present_primary if present_primary.any() else present_any
            uid = np.where(present, np.arange(1, npoints + 1), 0).astype(np.int32)
            entry.create_dataset("uniqueid", data=uid.reshape(shape))
            _classify(entry, groups, list(demands or {}), shape)
        os.replace(tmp, out)
    finally:
        if tmp.exists():
            tmp.unlink()
    return result


def _classify(
    entry: Any, groups: dict[str, dict[str, str]], axes: list[str], shape: tuple
) -> None:
    """NX_class attributes, the instrument's links, NXdata's signal/axes."""
    instrument = entry.create_group("instrument")
    instrument.attrs[_NX_CLASS] = "NXinstrument"
    for name, leaves in groups.items():
        group = entry[name]
        instrument[name] = group  # a hard link: the same group
        types = set(leaves.values())
        primary = [leaf for leaf, t in leaves.items() if t == "primary"]
        if primary:
            group.attrs[_NX_CLASS] = "NXdata"
            group.attrs["signal"] = primary[0]
            linked = []
            for axis in axes:
                demand = entry.get(f"{axis}/value_set")
                if demand is not None and f"{axis}_set" not in group:
                    group[f"{axis}_set"] = demand
                    linked.append(axis)
            ndim = len(shape)
            names = [f"{a}_set" for a in linked]
            frame_dims = group[primary[0]].ndim - ndim
            scan_axes = names if len(names) == ndim else ["."] * ndim
            group.attrs["axes"] = scan_axes + ["."] * frame_dims
            for i, axis in enumerate(linked):
                group.attrs[f"{axis}_set_indices"] = _axis_index(i, len(linked), ndim)
        elif types <= {"position_set", "position_value"}:
            group.attrs[_NX_CLASS] = "NXpositioner"
        else:
            group.attrs[_NX_CLASS] = "NXcollection"
    entry["uniqueid"].attrs["units"] = "point index + 1"


def _axis_index(i: int, naxes: int, ndim: int) -> int:
    """The scan dimension of the ``i``-th axis (outer to inner): a grid's
    axes one per dimension; a spiral's all in its one dimension."""
    if naxes == ndim:
        return i
    return max(0, ndim - 1)

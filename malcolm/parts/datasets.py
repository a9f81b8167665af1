"""The ``datasets`` table every scanning block reports (issue 13, §2): the
device-layer managers and the beamline's scan file.

GDA reads it (interop.md); a beamline's file assembler uses it to find each
device's data. Columns as pymalcolm's: ``name`` (``det.data``,
``x.value``...), ``filename`` (relative to fileDir), ``type`` (one of
:data:`DATASET_TYPES`), ``rank`` (dimensions of one point's value: a frame
2, a scalar 0), ``path`` (HDF5 path of the dataset) and ``uniqueid`` (HDF5
path of a 1-d int dataset giving each row's point: point index + 1).
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterable, Mapping
from typing import Any

from malcolm.core import BadValueError, NumberArrayMeta, StringArrayMeta, TableMeta

__all__ = [
    "DATASET_TYPES",
    "check_file_args",
    "dataset_rows",
    "datasets_meta",
    "new_h5_file",
]

#: the values of the ``type`` column
DATASET_TYPES = ("primary", "secondary", "monitor", "position_set", "position_value")


def datasets_meta(
    description: str = "Datasets this device writes in a scan",
) -> TableMeta:
    """The meta of a ``datasets`` attribute (read-only)."""
    return TableMeta(
        {
            "name": StringArrayMeta("Dataset name, e.g. det.data", label="Name"),
            "filename": StringArrayMeta("File it is in, relative to fileDir"),
            "type": StringArrayMeta(", ".join(DATASET_TYPES)),
            "rank": NumberArrayMeta("int32", "Dimensions of one point's value"),
            "path": StringArrayMeta("HDF5 path of the dataset"),
            "uniqueid": StringArrayMeta("HDF5 path of each row's uniqueId"),
        },
        description,
        tags=("widget:table",),
    )


def dataset_rows(rows: Iterable[Mapping[str, Any]]) -> dict[str, tuple[Any, ...]]:
    """The table value of ``rows`` (dicts of the columns); a ``type`` not in
    :data:`DATASET_TYPES` raises BadValueError naming the row."""
    rows = list(rows)
    for i, row in enumerate(rows):
        if row.get("type") not in DATASET_TYPES:
            raise BadValueError(
                f"datasets row {i}: type {row.get('type')!r} is not one of"
                f" {', '.join(DATASET_TYPES)}"
            )
    return datasets_meta().validate(rows)


def check_file_args(mri: str, file_dir: str, name: str) -> None:
    """Refuse (BadValueError naming ``<mri>.configure.<argument>``) a
    ``formatName`` that is not a plain file name, or a ``fileDir`` that cannot
    take the file: neither a writeable directory nor one that can be made in
    one. Nothing is checked without a ``fileDir`` (no file)."""
    if not file_dir:
        return
    if not name or "/" in name or name in (".", ".."):
        raise BadValueError(
            f"{mri}.configure.formatName: {name!r} is not a plain file name"
        )
    where = file_dir
    while not os.path.exists(where):
        parent = os.path.dirname(where.rstrip("/")) or "."
        if parent == where:
            break
        where = parent
    if not os.path.isdir(where) or not os.access(where, os.W_OK | os.X_OK):
        raise BadValueError(
            f"{mri}.configure.fileDir: cannot write {file_dir!r} ({where!r} is"
            " not a writeable directory)"
        )


def new_h5_file(path: str | os.PathLike[str], **kwargs: Any) -> Any:
    """A new, empty HDF5 file open for writing at ``path`` (its directory
    made if missing), replacing a file there: the old one is removed first,
    since HDF5 truncating an existing file took ~3 ms a file where removing
    it and making a new one takes 0.3 ms (a reader that has the old one open
    keeps reading it). Blocking: call it in a worker thread."""
    import h5py  # loaded with the first file, not at start-up

    os.makedirs(os.path.dirname(os.fspath(path)) or ".", exist_ok=True)
    with contextlib.suppress(FileNotFoundError):
        os.unlink(path)
    return h5py.File(path, "w", **kwargs)

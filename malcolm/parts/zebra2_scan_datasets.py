"""The ZebraManager's ``datasets`` table (no numpy: made at start-up).

The raw file's columns (:mod:`.zebra2_scan_file` writes them) and the rows
GDA reads about them (pymalcolm's columns: name, filename, type, rank,
path, uniqueid).
"""

from __future__ import annotations

from typing import Any

from .datasets import DATASET_TYPES, datasets_meta

__all__ = [
    "COLUMNS",
    "DATASET_TYPES",
    "POSITION",
    "TIMESTAMP",
    "UNIQUEID",
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

"""The Editor's tables as metas, and conversions between rows and records."""

from __future__ import annotations

from typing import Any

from malcolm.core import (
    BooleanArrayMeta,
    NumberArrayMeta,
    StringArrayMeta,
    TableMeta,
)


def layout_meta() -> TableMeta:
    """The palette: name, mri (the child's fullname), x, y, visible."""
    return TableMeta(
        {
            "name": StringArrayMeta("Child name", label="Name"),
            "mri": StringArrayMeta("Child block's mri", label="Fullname"),
            "x": NumberArrayMeta("float64", "X position on the canvas", label="X"),
            "y": NumberArrayMeta("float64", "Y position on the canvas", label="Y"),
            "visible": BooleanArrayMeta("Whether the child is active", label="Visible"),
        },
        "Children of the manager and where the GUI draws them",
        tags=("widget:flowgraph",),
        writeable=True,
    )


def exports_meta() -> TableMeta:
    return TableMeta(
        {
            "name": StringArrayMeta("Name of the manager field", label="Name"),
            "source": StringArrayMeta("CHILD.FIELD it mirrors", label="Source"),
            "description": StringArrayMeta("Description", label="Description"),
        },
        "Child fields exported as fields of the manager",
        tags=("widget:table",),
        writeable=True,
    )


def followers_meta() -> TableMeta:
    return TableMeta(
        {
            "name": StringArrayMeta("CHILD.ATTRIBUTE that follows", label="Name"),
            "source": StringArrayMeta("Manager attribute it follows", label="Source"),
        },
        "Child attributes set whenever a manager attribute changes",
        tags=("widget:table",),
        writeable=True,
    )


def fixed_meta() -> TableMeta:
    """The Fixed table: ``name`` (CHILD.ATTRIBUTE) and ``value`` as JSON text."""
    return TableMeta(
        {
            "name": StringArrayMeta("CHILD.ATTRIBUTE held fixed", label="Name"),
            "value": StringArrayMeta("Its value, as JSON text", label="Value"),
        },
        "Child attributes held at fixed values (written on load and reset)",
        tags=("widget:table",),
        writeable=True,
    )


def rows(table: dict[str, Any]) -> list[dict[str, Any]]:
    """Column-major table value -> list of row dicts."""
    columns = list(table)
    n = len(table[columns[0]]) if columns else 0
    return [{c: table[c][i] for c in columns} for i in range(n)]


def columns(meta: TableMeta, row_list: list[dict[str, Any]]) -> dict[str, Any]:
    return meta.validate(row_list)

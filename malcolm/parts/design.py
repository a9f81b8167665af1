"""Saved designs: the records a Manager's Editor saves and loads.

A design file is written in the definition language (see the design
document's "Save and load settings" example)::

    parts.ModelPart:       {name}
    parts.PalettePart:     name, xcoord, ycoord, visible
    parts.ExportPart:      name, source, description (optional)
    parts.FollowerPart:    name, source
    fixed.Int|Float|String|Bool|Enum|Table: name, value

:func:`load_design` reads one into a :class:`Design`, the records in file
order, checking every key and type (``file:line`` errors, all at once).
These are records only: the Manager/Editor gives them behaviour.
"""

from __future__ import annotations

import os
import types
import typing
from collections.abc import Mapping
from dataclasses import MISSING, dataclass, field, fields
from pathlib import Path
from typing import Any

from malcolm.config.errors import ConfigError, Problems, did_you_mean
from malcolm.config.yamlsections import Section, load_sections

__all__ = [
    "DESIGN_KINDS",
    "Design",
    "ExportPart",
    "FixedBool",
    "FixedEnum",
    "FixedFloat",
    "FixedInt",
    "FixedString",
    "FixedTable",
    "FollowerPart",
    "ModelPart",
    "PalettePart",
    "load_design",
]


@dataclass(frozen=True)
class ModelPart:
    """The design's model: what the Manager block says it conforms to."""

    name: str


@dataclass(frozen=True)
class PalettePart:
    """A child block on the canvas: where it is drawn and if it is active."""

    name: str
    xcoord: int
    ycoord: int
    visible: bool


@dataclass(frozen=True)
class ExportPart:
    """A child attribute (``source``: ``BLOCK.ATTR``) exported as ``name``."""

    name: str
    source: str
    description: str = ""


@dataclass(frozen=True)
class FollowerPart:
    """A child attribute (``name``) that follows manager attribute ``source``."""

    name: str
    source: str


@dataclass(frozen=True)
class FixedInt:
    """A child attribute (``BLOCK.ATTR``) held at an int."""

    name: str
    value: int


@dataclass(frozen=True)
class FixedFloat:
    """A child attribute held at a float (an int is accepted)."""

    name: str
    value: float


@dataclass(frozen=True)
class FixedString:
    name: str
    value: str


@dataclass(frozen=True)
class FixedBool:
    name: str
    value: bool


@dataclass(frozen=True)
class FixedEnum:
    """A child attribute held at one of its choices (the choice's text)."""

    name: str
    value: str


Row = dict[str, Any]


@dataclass(frozen=True)
class FixedTable:
    """A child table attribute held at ``value``: rows with the same columns."""

    name: str
    value: list[Row]

    @property
    def columns(self) -> list[str]:
        """The column names, in the order of the first row."""
        return list(self.value[0]) if self.value else []


#: kind -> record class, as saved designs name them
DESIGN_KINDS: dict[str, type] = {
    "parts.ModelPart": ModelPart,
    "parts.PalettePart": PalettePart,
    "parts.ExportPart": ExportPart,
    "parts.FollowerPart": FollowerPart,
    "fixed.Int": FixedInt,
    "fixed.Float": FixedFloat,
    "fixed.String": FixedString,
    "fixed.Bool": FixedBool,
    "fixed.Enum": FixedEnum,
    "fixed.Table": FixedTable,
}


@dataclass(frozen=True)
class Design:
    """A loaded design: its records in file order, and views by kind."""

    path: Path
    records: list[Any] = field(default_factory=list)
    #: (file, line) of each record, in the same order
    lines: list[tuple[str, int]] = field(default_factory=list)

    def of(self, cls: type) -> list[Any]:
        return [r for r in self.records if isinstance(r, cls)]

    @property
    def model(self) -> str | None:
        models = self.of(ModelPart)
        return models[0].name if models else None

    @property
    def palette(self) -> list[PalettePart]:
        return self.of(PalettePart)

    @property
    def exports(self) -> list[ExportPart]:
        return self.of(ExportPart)

    @property
    def followers(self) -> list[FollowerPart]:
        return self.of(FollowerPart)

    @property
    def fixed(self) -> list[Any]:
        fixed = tuple(c for k, c in DESIGN_KINDS.items() if k.startswith("fixed."))
        return [r for r in self.records if isinstance(r, fixed)]


_TYPE_NAMES = {str: "text", int: "an Int", float: "a Float", bool: "a Boolean"}


def _check(expected: Any, value: Any, section: Section, path: tuple) -> Any:
    """``value`` converted to ``expected``, or ConfigError at its line."""

    def fail(what: str) -> ConfigError:
        return ConfigError.at(
            section.file,
            section.line_of(path),
            f"{section.kind}: '{path[0]}' must be {what}, not {value!r}",
        )

    if expected is str:
        if not isinstance(value, str):
            raise fail("text")
        return value
    if expected is bool:
        if not isinstance(value, bool):
            raise fail("a Boolean (Yes/No, true/false)")
        return value
    if expected is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise fail("an Int")
        return value
    if expected is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise fail("a Float")
        return float(value)
    if typing.get_origin(expected) is list:
        if not isinstance(value, list):
            raise fail("a list of rows")
        problems = Problems()
        rows: list[Row] = []
        for i, row in enumerate(value):
            where = section.line_of((*path, i))
            if not isinstance(row, Mapping) or not row:
                problems.add(
                    section.file,
                    where,
                    f"{section.kind}: row {i + 1} must be a mapping of "
                    f"column: value, not {row!r}",
                )
                continue
            if rows and list(row) != list(rows[0]):
                problems.add(
                    section.file,
                    where,
                    f"{section.kind}: row {i + 1} has columns {list(row)}, "
                    f"expected {list(rows[0])} (as in row 1)",
                )
                continue
            rows.append(dict(row))
        problems.raise_if_any()
        return rows
    return value  # pragma: no cover - every field type is handled above


def _record(section: Section, cls: type) -> Any:
    problems = Problems()
    hints = typing.get_type_hints(cls)
    known = {f.name: f for f in fields(cls)}
    kwargs: dict[str, Any] = {}
    for key, value in section.params.items():
        if key not in known:
            problems.add(
                section.file,
                section.line_of((key,)),
                f"{section.kind}: unknown key '{key}' (expected "
                f"{', '.join(known)})" + did_you_mean(key, known),
            )
            continue
        with problems.collect():
            expected = hints[key]
            if isinstance(expected, types.UnionType):  # pragma: no cover
                expected = typing.get_args(expected)[0]
            kwargs[key] = _check(expected, value, section, (key,))
    for name, f in known.items():
        if name not in section.params and f.default is MISSING:
            problems.add(section.file, section.line, f"{section.kind} needs a '{name}'")
    problems.raise_if_any()
    return cls(**kwargs)


def load_design(path: str | os.PathLike[str]) -> Design:
    """Read a saved design; every problem of the file raised at once."""
    design = Design(Path(path))
    problems = Problems()
    for section in load_sections(path):
        cls = DESIGN_KINDS.get(section.kind)
        if cls is None:
            problems.add(
                section.file,
                section.line,
                f"unknown design section '{section.kind}'"
                + did_you_mean(section.kind, DESIGN_KINDS),
            )
            continue
        with problems.collect():
            design.records.append(_record(section, cls))
            design.lines.append((section.file, section.line))
    problems.problems.sort(key=lambda p: p.line)
    problems.raise_if_any()
    return design

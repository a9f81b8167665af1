"""``*CHANGES`` lines and table words, as data.

- :func:`parse_change`: ``!PCOMP1.START=5`` / ``!SEQ.TABLE<`` /
  ``!SYSTEM.TEMP (error)`` (without the ``!``) -> a :class:`Change`;
- :func:`unpack_table` / :func:`pack_table`: a table's 32-bit words <->
  columns, from the bit ranges of ``B1.TABLE.FIELDS?``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from .layout import TableColumn

__all__ = ["Change", "pack_table", "parse_change", "unpack_table"]


@dataclass(frozen=True, slots=True)
class Change:
    """One ``*CHANGES`` line: ``block`` is the instance (``PCOMP1``, ``SEQ``),
    ``attribute`` is None for the field's value; ``kind`` is ``value``,
    ``table`` (re-read it) or ``error`` (unreadable)."""

    block: str
    field: str
    attribute: str | None
    kind: str
    value: str = ""


def parse_change(line: str) -> Change | None:
    """The change a line reports, or None (metadata, or not understood)."""
    if line.startswith("*"):
        return None
    if line.endswith(" (error)"):
        name, kind, value = line[: -len(" (error)")], "error", ""
    elif line.endswith("<") and "=" not in line:
        name, kind, value = line[:-1], "table", ""
    else:
        name, sep, value = line.partition("=")
        if not sep:
            return None
        kind = "value"
    parts = name.split(".")
    if len(parts) == 2:
        return Change(parts[0], parts[1], None, kind, value)
    if len(parts) == 3:
        return Change(parts[0], parts[1], parts[2], kind, value)
    return None


def _signed(value: int, bits: int) -> int:
    return value - (1 << bits) if value >> (bits - 1) & 1 else value


def unpack_table(
    columns: Sequence[TableColumn], row_words: int, words: Sequence[int]
) -> dict[str, list[Any]]:
    """Columns of a table from its words (``row_words`` words a row)."""
    out: dict[str, list[Any]] = {c.name: [] for c in columns}
    n = len(words) // row_words if row_words else 0
    for r in range(n):
        row = 0
        for i, w in enumerate(words[r * row_words : (r + 1) * row_words]):
            row |= (int(w) & 0xFFFFFFFF) << (32 * i)
        for c in columns:
            bits = c.high - c.low + 1
            v = (row >> c.low) & ((1 << bits) - 1)
            if c.subtype == "enum":
                out[c.name].append(c.labels[v] if v < len(c.labels) else str(v))
            elif c.subtype == "int":
                out[c.name].append(_signed(v, bits))
            else:
                out[c.name].append(v)
    return out


def pack_table(
    columns: Sequence[TableColumn], row_words: int, table: Mapping[str, Sequence[Any]]
) -> list[int]:
    """The words of a table given as columns (missing columns are 0)."""
    n = max((len(table.get(c.name, ())) for c in columns), default=0)
    words: list[int] = []
    for r in range(n):
        row = 0
        for c in columns:
            col = table.get(c.name, ())
            v: Any = col[r] if r < len(col) else 0
            if c.subtype == "enum":
                v = c.labels.index(v) if v in c.labels else int(v)
            bits = c.high - c.low + 1
            row |= (int(v) & ((1 << bits) - 1)) << c.low
        words += [(row >> (32 * i)) & 0xFFFFFFFF for i in range(row_words)]
    return words

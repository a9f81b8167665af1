"""The table issue 8's benchmarks print: each figure beside its target and
the reference implementation's (pymalcolm 6.3) figure from the issue."""

from __future__ import annotations

import os
import statistics
from collections.abc import Sequence
from dataclasses import dataclass


@dataclass(frozen=True)
class Row:
    """One case: what was measured, its target and the reference's figure
    (text as the issue gives them, "-" where it gives none)."""

    case: str
    measured: float
    unit: str
    target: str
    reference: str
    note: str = ""

    @property
    def value(self) -> str:
        return f"{self.measured:.4g} {self.unit}"


HEADER = ("case", "measured", "target", "reference", "note")


def render(rows: Sequence[Row], source: str = "reference figures from issue 8") -> str:
    """The rows as an aligned text table, with the machine's load below and
    ``source``: where the targets and reference figures come from."""
    cells = [HEADER] + [(r.case, r.value, r.target, r.reference, r.note) for r in rows]
    widths = [max(len(c[i]) for c in cells) for i in range(len(HEADER))]
    lines = ["  ".join(c[i].ljust(widths[i]) for i in range(len(HEADER))).rstrip()
             for c in cells]  # fmt: skip
    lines.insert(1, "  ".join("-" * w for w in widths))
    lines.append(machine_load(source))
    return "\n".join(lines)


def machine_load(source: str = "reference figures from issue 8") -> str:
    """The load averages and cores, to judge the figures by, and ``source``."""
    one, five, fifteen = os.getloadavg()
    tail = f"; {source}" if source else ""
    return (
        f"(machine: {os.cpu_count()} cores, load average {one:.2f} {five:.2f}"
        f" {fifteen:.2f}{tail})"
    )


def median(values: Sequence[float]) -> float:
    return statistics.median(values)

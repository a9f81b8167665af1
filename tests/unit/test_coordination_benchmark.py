"""``benchmarks/coordination.py`` prints its table (run small here; its
figures depend on the machine and are not asserted: the target is in the
table and the report)."""

from __future__ import annotations

import asyncio

from benchmarks import coordination
from benchmarks.table import HEADER, render


def test_the_coordination_benchmark_prints_its_table() -> None:
    rows = asyncio.run(coordination.measure(repeats=2))
    assert all(r.measured > 0 for r in rows)
    lines = render(rows, coordination.SOURCE).splitlines()
    assert lines[0].split() == list(HEADER)
    cases = [line.split(":")[0] for line in lines[2:-1]]
    assert cases == ["10x10 grid"] * 3 + ["10,000-point spiral"] * 3
    assert [r.unit for r in rows] == ["ms", "ms", "x"] * 2
    assert rows[2].note == coordination.RATIO_NOTE
    assert lines[-1].startswith("(machine: ")

"""``benchmarks/startup.py`` and ``benchmarks/demo_scan.py`` print their
tables (run small here; their figures depend on the machine and are not
asserted: the targets are in the tables and the report)."""

from __future__ import annotations

import asyncio

from benchmarks import demo_scan, startup
from benchmarks.table import HEADER, render


def check_table(text: str, cases: list[str]) -> None:
    lines = text.splitlines()
    assert lines[0].split() == list(HEADER)
    assert [line[: len(c)] for line, c in zip(lines[2:], cases)] == cases
    assert lines[-1].startswith("(machine: ")


def test_the_startup_benchmark_prints_its_table() -> None:
    rows = startup.rows(runs=1, blocks=3, interpreters=1)
    assert all(r.measured > 0 for r in rows)
    check_table(
        render(rows),
        [
            "malcolm demo, start to ready",
            "3 blocks x 10 attributes, build+start (as malcolm serve)",
            "3 blocks x 10 attributes, build+start (plain API)",
        ],
    )


def test_the_demo_scan_benchmark_prints_its_table() -> None:
    rows = asyncio.run(demo_scan.measure(points=12, size=4, repeats=1))
    assert all(r.measured >= 0 for r in rows)
    check_table(
        render(rows),
        [
            "demo scan overhead/point at 1 ms",
            "  one asyncio.sleep(duration) a point",
            "  demo scan work/point (1 us exposure)",
            "loop stall, configure 4x4 snake grid",
            "  same points computed on the loop",
            "loop stall, configure 4x4 spiral",
            "  same points computed on the loop",
            "loop stall, configure 4x4 grid, circle region",
            "  same points computed on the loop",
        ],
    )

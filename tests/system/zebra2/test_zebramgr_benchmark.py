"""``benchmarks/zebramgr.py`` prints its table (once each here, on
127.0.0.1:8888/8889 of the isolated namespace; its figures depend on the
machine and are not asserted: the targets are in the table and the
report)."""

from __future__ import annotations

import asyncio

from benchmarks import zebramgr
from benchmarks.table import HEADER, render


def test_the_zebramgr_benchmark_prints_its_table() -> None:
    proc = zebramgr.start_sim()
    try:
        rows = asyncio.run(zebramgr.main(zebramgr.parse(["--repeats", "1"])))
    finally:
        zebramgr.stop_sim(proc)
    assert all(r.measured > 0 for r in rows)
    lines = render(rows, zebramgr.SOURCE).splitlines()
    assert lines[0].split() == list(HEADER)
    cases = [
        "configure, 10x10 snake grid",
        "configure, 10,000-point spiral",
        "run overhead per point, 10,000 at 100 us",
    ]
    assert [line[: len(c)] for line, c in zip(lines[2:], cases)] == cases
    assert "issue 13" in lines[-1]

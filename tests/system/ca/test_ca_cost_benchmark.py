"""``benchmarks/ca_cost.py`` prints its table (a short run here; its
figures depend on the machine and are not asserted beyond being
measured: they are in the report)."""

from __future__ import annotations

from benchmarks import ca_cost
from benchmarks.table import HEADER, render


def test_the_ca_cost_benchmark_measures_both_operations() -> None:
    rows = ca_cost.measure(n=20, rounds=1, seconds=0.3)
    assert [r.case for r in rows] == [
        "put+readback CPU, block / raw pyepics",
        "monitor event CPU, block / raw pyepics",
    ]
    assert all(r.measured > 0 for r in rows)
    lines = render(rows, ca_cost.SOURCE).splitlines()
    assert lines[0].split() == list(HEADER)

"""``benchmarks/phases.py`` still prints its table (its figures are not
asserted: they depend on the machine; the issue's target is in the report)."""

from __future__ import annotations

import asyncio

from benchmarks import phases


def test_the_benchmark_prints_its_table(capsys):
    asyncio.run(phases.main(repeats=2, steps=10))
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].split() == ["case", "malcolm", "raw", "ratio", "target"]
    names = [line[:36].strip() for line in lines[1:5]]
    assert names == [
        "configure, 1 no-op parts (ms)",
        "configure, 10 no-op parts (ms)",
        "configure, 100 no-op parts (ms)",
        "run cycles/s, 1 step/run x 10",
    ]
    for line in lines[1:5]:
        malcolm, raw, ratio = (float(x) for x in line[36:].split()[:3])
        assert malcolm > 0 and raw > 0 and ratio > 0
    assert lines[5].startswith("(ratio = malcolm cost / raw cost")

"""``benchmarks/phases.py`` still prints its table (its figures are not
asserted: they depend on the machine; the issue's target is in the report),
and configures a scan it has not seen before on each repeat, as GDA does
(review A, F2): no cache of built scans makes its figure a repeat's."""

from __future__ import annotations

import asyncio
from typing import Any

import pytest

import malcolm.scan.load
from benchmarks import phases


def test_the_benchmark_prints_its_table(capsys):
    asyncio.run(phases.main(repeats=2, steps=10))
    lines = capsys.readouterr().out.splitlines()
    width = phases.WIDTH
    assert lines[0].split() == ["case", "malcolm", "raw", "ratio", "target"]
    names = [line[:width].strip() for line in lines[1:5]]
    assert names == [
        "configure a new scan, 1 no-op parts (ms)",
        "configure a new scan, 10 no-op parts (ms)",
        "configure a new scan, 100 no-op parts (ms)",
        "run cycles/s, 1 step/run x 10",
    ]
    for line in lines[1:5]:
        malcolm, raw, ratio = (float(x) for x in line[width:].split()[:3])
        assert malcolm > 0 and raw > 0 and ratio > 0
    assert lines[1].endswith("<= 3.0")  # the figure beside its target
    assert lines[5].startswith("(ratio = malcolm cost / raw cost")
    assert "planning the new scan" in lines[6]


@pytest.fixture
def built(monkeypatch: pytest.MonkeyPatch) -> list[Any]:
    """The generators whose scans are built from now on."""
    seen: list[Any] = []
    real = malcolm.scan.load.points_from_data

    def counting(generator: Any) -> Any:
        seen.append(generator)
        return real(generator)

    monkeypatch.setattr(malcolm.scan.load, "points_from_data", counting)
    return seen


def test_every_configure_of_the_benchmark_builds_a_new_scan(built):
    asyncio.run(phases.configure_case(1, repeats=6))
    assert len(built) == 6
    assert len({repr(generator) for generator in built}) == 6

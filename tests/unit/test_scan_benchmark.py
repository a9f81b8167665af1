"""benchmarks/scan.py measures the scans issue 8 names (not how fast: the
benchmark prints that; this checks it measures the right thing)."""

from __future__ import annotations

from benchmarks.scan import cases, configure
from malcolm.scan import scan_points


def test_the_benchmark_cases_are_the_scans_of_issue_8():
    found = {case.name: case for case in cases()}
    region = found.pop("1e8 grid, circle region")  # evaluated when built: slow
    sizes = {name: scan_points(case.generator).size for name, case in found.items()}
    assert sizes == {
        "1000x1000 grid": 1_000_000,
        "1e6-point spiral": 1_000_000,
        "1e8-point snake grid": 100_000_000,
    }
    assert (
        region.generator["generators"]
        == found["1e8-point snake grid"].generator["generators"]
    )
    assert len(region.generator["excluders"]) == 1
    snake = scan_points(found["1e8-point snake grid"].generator)
    assert [d.snake for d in snake.dimensions] == [False, True]
    for name in ("1000x1000 grid", "1e8-point snake grid"):
        spec = found[name].spec
        assert spec is not None
        assert spec.shape() == tuple(scan_points(found[name].generator).shape)
    configure(found["1e6-point spiral"])  # validate, build, steps, first chunk

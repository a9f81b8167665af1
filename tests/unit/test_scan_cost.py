"""The cheap-build predicate (`malcolm.scan.cost`): which scans are cheap
enough to build on the event loop (issue 7's configure target; issue 8:
work of more than a few milliseconds stays off the loop)."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from typing import Any

import pytest

import malcolm.scan.compound
from malcolm.controllers.scan_steps import plans_on_loop
from malcolm.scan import build_cost, cheap_to_build, gda, scan_points
from malcolm.scan.cost import CHEAP_BUILD_COST, DATA_ITEM_COST

ROI = "scanpointgenerator:roi/"


def with_region(generator: dict[str, Any], *rois: dict[str, Any]) -> dict[str, Any]:
    """``generator`` with an ROIExcluder of ``rois`` on x and y."""
    excluder = {
        "typeid": "scanpointgenerator:excluder/ROIExcluder:1.0",
        "axes": ["x", "y"],
        "rois": list(rois),
    }
    return {**generator, "excluders": [excluder]}


def circle(radius: float = 0.4) -> dict[str, Any]:
    return {
        "typeid": ROI + "CircularROI:1.0",
        "centre": [0.5, 0.5],
        "radius": radius,
    }


def grid(ny: int, nx: int) -> dict[str, Any]:
    return gda.compound(gda.line("y", ny), gda.line("x", nx, alternate=True))


def array(n: int) -> dict[str, Any]:
    return gda.compound(
        {
            "typeid": gda.PREFIX + "ArrayGenerator:1.0",
            "axes": ["x"],
            "points": [float(i) for i in range(n)],
        }
    )


def test_a_small_grid_is_cheap() -> None:
    assert cheap_to_build(grid(3, 4))
    assert cheap_to_build({"generator": grid(3, 4)})  # as configure has it


def test_a_big_grid_without_a_region_is_cheap() -> None:
    """Building a grid computes no point, whatever its size."""
    assert cheap_to_build(grid(10_000, 10_000))


def test_a_region_over_1e8_points_is_costly() -> None:
    generator = with_region(grid(10_000, 10_000), circle())
    assert build_cost(generator) >= 1e8
    assert not cheap_to_build(generator)


def test_a_region_over_a_small_grid_is_cheap_and_over_a_big_one_costly() -> None:
    assert cheap_to_build(with_region(grid(10, 10), circle()))
    assert not cheap_to_build(with_region(grid(200, 200), circle()))


def test_a_region_counts_only_the_dimensions_it_joins() -> None:
    """A circle on x and y inside a 1000-point outer line: the 10 x 10 it
    joins is evaluated once, not for each of the outer points."""
    generator = with_region(
        gda.compound(gda.line("z", 1000), gda.line("y", 10), gda.line("x", 10)),
        circle(),
    )
    assert cheap_to_build(generator)


def test_a_big_explicit_array_is_costly_and_a_small_one_cheap() -> None:
    assert cheap_to_build(array(10))
    assert not cheap_to_build(array(10_000))


def test_scanspec_and_what_is_not_understood_are_costly() -> None:
    serialized = {"type": "Line", "axis": "x", "start": 0, "stop": 1, "num": 5}
    assert not cheap_to_build(serialized)
    unknown = gda.compound({"typeid": gda.PREFIX + "NewGenerator:9.0", "size": 3})
    assert not cheap_to_build(unknown)
    bad_size = gda.compound(gda.line("y", 3), {**gda.line("x", 3), "size": "many"})
    assert not cheap_to_build(with_region(bad_size, circle()))
    lost_axis = with_region(gda.compound(gda.line("x", 3)), circle())  # no y
    assert not cheap_to_build(lost_axis)


def test_scan_points_and_text_are_cheap() -> None:
    """ScanPoints are built already; text is refused before it is read."""
    assert cheap_to_build(scan_points(grid(2, 2)))
    assert cheap_to_build("/etc/passwd")


class Unread(list):
    """A list that fails if its items are looked at."""

    def __iter__(self) -> Any:
        raise AssertionError("the items past the limit were looked at")


def test_counting_stops_past_the_limit() -> None:
    """A million-item list is found costly from its length: its items are
    never looked at (the estimate costs no more than the limit allows)."""
    huge = {**grid(2, 2), "extra": Unread(range(1_000_000))}
    assert build_cost(huge, CHEAP_BUILD_COST) > CHEAP_BUILD_COST
    assert not cheap_to_build(huge)


@pytest.mark.parametrize(
    "generator",
    [
        with_region(grid(30, 40), circle()),
        with_region(grid(64, 64), circle(), circle(0.1)),
        with_region(
            gda.compound(gda.line("z", 5), gda.line("y", 20), gda.line("x", 30)),
            {
                "typeid": ROI + "PolygonalROI:1.0",
                "points_x": [0, 1, 0.5],
                "points_y": [0, 0, 1],
            },
        ),
        with_region(
            gda.compound(gda.line("y", 20), gda.line("z", 7), gda.line("x", 30)),
            circle(),
        ),
    ],
)
def test_the_estimate_is_never_below_the_points_a_region_evaluates(
    monkeypatch: pytest.MonkeyPatch, generator: dict[str, Any]
) -> None:
    evaluated: list[int] = []
    real = malcolm.scan.compound.find_runs

    def counting(full: int, keep: Any, chunk: int | None = None) -> Any:
        evaluated.append(full)
        return real(full, keep, chunk)

    monkeypatch.setattr(malcolm.scan.compound, "find_runs", counting)
    malcolm.scan.compound.compound_points(generator)
    assert evaluated  # the region was evaluated
    assert build_cost(generator) >= sum(evaluated)


def test_plans_on_loop_counts_breakpoints_and_takes_built_points() -> None:
    import malcolm.scan.load  # noqa: F401  (the builders are loaded)

    small = grid(3, 4)
    assert plans_on_loop({"generator": small})
    assert plans_on_loop({"generator": small, "breakpoints": [6, 6]})
    many = [1] * (CHEAP_BUILD_COST // DATA_ITEM_COST + 1)
    assert not plans_on_loop({"generator": small, "breakpoints": many})
    assert not plans_on_loop({"generator": with_region(grid(200, 200), circle())})
    built = scan_points(with_region(grid(200, 200), circle()))
    assert plans_on_loop({"generator": built})


def test_the_predicate_imports_neither_numpy_nor_the_builders() -> None:
    """It runs on the loop before any scan is built: the first configure of
    a process must not import numpy there."""
    code = textwrap.dedent(
        """
        import sys
        from malcolm.controllers.scan_steps import plans_on_loop
        from malcolm.scan import cheap_to_build, gda
        assert cheap_to_build(gda.compound(gda.line("x", 3)))
        # the first scan is planned in the thread: its import is costly
        assert not plans_on_loop({"generator": gda.compound(gda.line("x", 3))})
        loaded = [m for m in ("numpy", "malcolm.scan.load") if m in sys.modules]
        assert not loaded, loaded
        """
    )
    subprocess.run([sys.executable, "-c", code], check=True)

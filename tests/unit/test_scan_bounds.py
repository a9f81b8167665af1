"""A curve's bounds over consecutive points are evaluated once (each
point's upper bound is the next one's lower), to the same values as
point by point."""

from __future__ import annotations

import numpy as np

from malcolm.scan import gda, scan_points
from malcolm.scan.dimensions import _consecutive


def test_a_spirals_bounds_are_those_of_each_point():
    points = scan_points(gda.compound(gda.spiral("x", "y", 0.5, scale=0.01)))
    gen = points._dims[0].generators[0]
    for start, stop in ((0, points.size), (17, 404), (5, 6)):
        chunk = points.chunk(start, stop)
        index = np.arange(start, stop)
        low, high = gen.bounds_at(index), gen.bounds_at(index + 1)
        for axis in ("x", "y"):
            assert np.array_equal(chunk.lower[axis], low[axis])
            assert np.array_equal(chunk.upper[axis], high[axis])
            assert not chunk.lower[axis].flags.writeable


def test_a_snake_still_swaps_its_bounds_backwards():
    points = scan_points(
        gda.compound(gda.line("y", 3, 0, 2), gda.line("x", 4, 0, 3, alternate=True))
    )
    chunk = points.chunk(0, points.size)
    # the second row runs backwards: its lower bounds are above its points
    row = slice(4, 8)
    assert np.all(chunk.lower["x"][row] > chunk.positions["x"][row])
    assert np.all(chunk.upper["x"][:4] > chunk.positions["x"][:4])


def test_consecutive():
    assert _consecutive(np.arange(3, 9))
    assert not _consecutive(np.array([3]))
    assert not _consecutive(np.array([3, 5, 4, 6]))  # ends agree, middle not
    assert not _consecutive(np.array([0, 2]))

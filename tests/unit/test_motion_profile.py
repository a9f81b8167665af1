"""The trajectory profile a MotorControllerManager builds from a scan's
points (malcolm.parts.motion_profile), without an IOC."""

from __future__ import annotations

import numpy as np
import pytest

from malcolm.parts.motion_profile import ProfileError, build_profile, too_fast
from malcolm.scan import gda, scan_points


def profile_of(generator, start=0, stop=None, accel=0.1, velocity=10.0):
    points = scan_points(generator)
    stop = points.size if stop is None else stop
    axes = list(points.axes)
    chunk = points.chunk(start, stop, axes)
    return build_profile(
        start,
        chunk.lower,
        chunk.positions,
        chunk.upper,
        chunk.duration,
        accel,
        {a: velocity for a in axes},
        axes,
    )


def test_a_line_is_a_run_up_then_midpoints_and_ends():
    p = profile_of(gda.compound(gda.line("x", 3, 0.0, 1.0), duration=0.5))
    assert p.positions["x"].tolist() == [-0.25, 0.0, 0.25, 0.5, 0.75, 1.0, 1.25]
    assert p.times.tolist() == [100_000] + [250_000] * 6
    # each point's exposure starts at its lower bound: a trigger there
    assert p.indices.tolist() == [0, -1, 1, -1, 2, -1, -1]
    assert p.point_of.tolist() == [-1, 0, -1, 1, -1, 2, -1]
    assert p.done_after.tolist() == [0, 0, 1, 1, 2, 2, 3]
    # the run-up: one acceleration distance (1 mm/s * 0.1 s / 2) before
    assert p.run_up == {"x": pytest.approx(-0.25 - 0.05)}
    assert p.demands["x"].tolist() == [0.0, 0.5, 1.0]


def test_a_snake_turns_round_between_rows_and_counts_from_its_start():
    snake = gda.compound(
        gda.line("y", 2, 0.0, 1.0),
        gda.line("x", 3, 0.0, 1.0, alternate=True),
        duration=0.5,
    )
    p = profile_of(snake)
    assert p.size == 1 + 2 * 6 + 1
    turn = 7  # the second row's lower bound, after the first row's end
    assert (p.positions["x"][turn], p.positions["y"][turn]) == (1.25, 1.0)
    # 2 * accel, and 1 mm of y at 10 mm/s
    assert p.times[turn] == 300_000
    assert p.indices[turn] == 3 and p.done_after[turn] == 3
    # a later run (steps 3..5) numbers its points from 3
    later = profile_of(snake, start=3)
    assert later.point_of[later.point_of >= 0].tolist() == [3, 4, 5]
    assert later.done_after[-1] == 6
    assert later.run_up["x"] == pytest.approx(1.25 + 0.05)


def test_a_spiral_of_10000_points_is_2n_plus_1_profile_points():
    spiral = gda.compound(gda.spiral("x", "y", 5.64, 0.1), duration=0.01)
    p = profile_of(spiral)
    n = scan_points(spiral).size
    assert p.size == 2 * n + 1
    assert np.all(p.times > 0)
    assert sorted(p.indices[p.indices >= 0].tolist()) == list(range(n))


def test_bad_durations_are_refused():
    with pytest.raises(ProfileError, match="positive duration"):
        build_profile(0, {"x": [0.0]}, {"x": [0.0]}, {"x": [0.0]}, [0.0], 0.1,
                      {"x": 1.0}, ["x"])  # fmt: skip
    with pytest.raises(ProfileError, match="under 2 microseconds"):
        build_profile(0, {"x": [0.0]}, {"x": [0.0]}, {"x": [0.0]}, [1e-6], 0.1,
                      {"x": 1.0}, ["x"])  # fmt: skip


def test_too_fast_finds_the_fastest_point_over_the_limit():
    lower = np.array([0.0, 1.0, 2.0])
    upper = np.array([1.0, 3.0, 2.5])
    assert too_fast(lower, upper, np.array([1.0, 1.0, 1.0]), 5.0) is None
    assert too_fast(lower, upper, np.array([1.0, 1.0, 1.0]), 1.5) == (1, 2.0)

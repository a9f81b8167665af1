"""The simulated motor's move in time (malcolm.sim.beamline_ioc.trapezoid)."""

import math

import pytest

from malcolm.sim.beamline_ioc.trapezoid import move_time, moved_by

VELO, ACCL = 10.0, 0.1  # the simulated motors' defaults: 10 mm/s, 0.1 s


def test_a_tiny_move_takes_far_less_than_the_acceleration_time():
    # nanometres: a triangle of 2 * sqrt(d / a), a = VELO / ACCL
    assert move_time(1e-6, VELO, ACCL) == pytest.approx(2 * math.sqrt(1e-6 / 100))
    assert move_time(1e-6, VELO, ACCL) < ACCL / 100
    assert move_time(0.0, VELO, ACCL) == 0.0


def test_move_time_grows_with_distance_and_is_a_trapezoid_past_the_ramps():
    distances = [1e-9, 1e-6, 1e-3, 0.5, 1.0, 2.0, 50.0]
    times = [move_time(d, VELO, ACCL) for d in distances]
    assert times == sorted(times) and len(set(times)) == len(times)
    # far enough to reach VELO: d / VELO plus ACCL (half of each ramp lost)
    assert move_time(50.0, VELO, ACCL) == pytest.approx(5.0 + ACCL)
    # exactly the two ramps' distance: triangle and trapezoid agree
    edge = VELO * ACCL
    assert move_time(edge * (1 - 1e-12), VELO, ACCL) == pytest.approx(
        move_time(edge, VELO, ACCL)
    )
    assert move_time(-2.0, VELO, ACCL) == move_time(2.0, VELO, ACCL)
    assert move_time(2.0, VELO, 0.0) == pytest.approx(0.2)  # no ramps


@pytest.mark.parametrize("distance", [1e-6, 0.5, 1.0, 3.0])
def test_the_position_along_a_move_is_continuous_and_ends_at_the_target(distance):
    total = move_time(distance, VELO, ACCL)
    ts = [total * i / 400 for i in range(401)]
    along = [moved_by(t, distance, VELO, ACCL) for t in ts]
    assert along[0] == 0.0 and along[-1] == pytest.approx(distance)
    assert along == sorted(along)  # never goes back
    steps = [b - a for a, b in zip(along, along[1:], strict=False)]
    # no jump: no step faster than VELO over its interval
    assert max(steps) <= VELO * total / 400 * (1 + 1e-9)
    assert moved_by(total * 2, distance, VELO, ACCL) == distance

"""A motor record's move in time: a trapezoidal velocity profile.

``accl`` seconds to reach ``velocity``, at ``velocity``, ``accl`` seconds
to stop; a distance too short to reach ``velocity`` is a triangle of
``2 * sqrt(d / a)`` seconds (``a = velocity / accl``). Plain maths, apart
from the IOC (which imports softioc) so that it can be tested alone.
"""

from __future__ import annotations

import math

__all__ = ["move_time", "moved_by"]


def move_time(distance: float, velocity: float, accl: float) -> float:
    """Seconds a trapezoidal move of ``distance`` takes at ``velocity``,
    ``accl`` seconds to reach it and as many to stop (a triangle if the
    distance is too short to reach it)."""
    d = abs(distance)
    if d == 0.0:
        return 0.0
    if accl <= 0.0:
        return d / velocity
    if d >= velocity * accl:  # accelerating and stopping cover velocity * accl
        return d / velocity + accl
    return 2.0 * math.sqrt(d * accl / velocity)


def moved_by(elapsed: float, distance: float, velocity: float, accl: float) -> float:
    """How far along (0..|distance|) a trapezoidal move is after ``elapsed``."""
    d = abs(distance)
    total = move_time(d, velocity, accl)
    if elapsed >= total:
        return d
    if accl <= 0.0:
        return velocity * elapsed
    ramp = min(accl, total / 2)  # the time accelerating (and stopping)
    a = velocity / accl
    peak = a * ramp
    if elapsed <= ramp:
        return a * elapsed * elapsed / 2
    if elapsed <= total - ramp:
        return a * ramp * ramp / 2 + peak * (elapsed - ramp)
    left = total - elapsed
    return d - a * left * left / 2

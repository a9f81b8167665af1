"""A trajectory-scan profile from a scan's points, in numpy (no per-point loop).

:func:`build_profile` turns the steps ``start .. stop-1`` of a scan (their
lower bounds, positions, upper bounds and durations) into the arrays a
pmac-like trajectory controller walks:

- a **run-up**: the first profile point is the first step's lower bound,
  reached ``accel`` seconds after the start; the motors wait at the start,
  one acceleration distance (``v * accel / 2``, ``v`` the first step's speed)
  before it, so the first step is crossed at speed;
- per step: its **midpoint** (half its duration) and its **upper bound**
  (the other half); where a step's upper bound is the next step's lower
  bound (a line, a spiral, a row of a grid) nothing else is needed;
- a **turnaround** where it is not (the next row of a snake): the next
  step's lower bound, after ``2 * accel`` plus the longest of the axes'
  moves at their velocity.

``indices`` marks where each step's exposure starts (its lower bound: a
trigger) with the step's index, -1 elsewhere; ``point_of`` marks each
step's midpoint with its index (where its readback is taken), -1 elsewhere;
``done_after`` is the steps complete once a profile point is reached.
Times are whole microseconds, each at least one.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["Profile", "ProfileError", "build_profile", "too_fast"]

#: two bounds closer than this are the same place
SAME_PLACE = 1e-9


class ProfileError(ValueError):
    """A scan the trajectory cannot do; the message says why."""


@dataclass
class Profile:
    """The arrays of one run's trajectory (one entry per profile point)."""

    start_step: int
    stop_step: int
    #: scan axis -> the profile points' positions
    positions: dict[str, np.ndarray]
    #: microseconds to reach each profile point from the last (int32)
    times: np.ndarray
    #: the step whose exposure starts at each profile point, or -1 (int32)
    indices: np.ndarray
    #: the step whose midpoint each profile point is, or -1 (int32)
    point_of: np.ndarray
    #: steps complete once each profile point is reached (int32)
    done_after: np.ndarray
    #: scan axis -> where the motor waits before the run (the run-up start)
    run_up: dict[str, float]
    #: scan axis -> each step's position (the demand, value_set)
    demands: dict[str, np.ndarray]

    @property
    def size(self) -> int:
        return len(self.times)


def too_fast(
    lower: np.ndarray, upper: np.ndarray, duration: np.ndarray, vmax: float
) -> tuple[int, float] | None:
    """``(step offset, speed)`` of the fastest step of one axis if it needs
    more than ``vmax``, else None."""
    speed = np.abs(upper - lower) / duration
    worst = int(np.argmax(speed)) if len(speed) else 0
    if len(speed) and speed[worst] > vmax:
        return worst, float(speed[worst])
    return None


def _whole_us(seconds: np.ndarray) -> np.ndarray:
    return np.rint(seconds * 1e6).astype(np.int64)


def build_profile(
    start: int,
    lower: Mapping[str, np.ndarray],
    positions: Mapping[str, np.ndarray],
    upper: Mapping[str, np.ndarray],
    duration: np.ndarray,
    accel: float,
    velocity: Mapping[str, float],
    axes: Sequence[str],
) -> Profile:
    """The profile of steps ``start .. start + len(duration) - 1`` of
    ``axes`` (each given in ``lower``/``positions``/``upper``); ``accel`` is
    the acceleration time (s), ``velocity`` each axis's speed for moves."""
    n = len(duration)
    if n == 0:
        raise ProfileError("no steps to do")
    duration = np.asarray(duration, dtype=float)
    if np.any(~np.isfinite(duration)) or np.any(duration <= 0):
        raise ProfileError("every point needs a positive duration")
    total_us = _whole_us(duration)
    if np.any(total_us < 2):
        raise ProfileError("a point's duration is under 2 microseconds")
    low = {a: np.asarray(lower[a], dtype=float) for a in axes}
    mid = {a: np.asarray(positions[a], dtype=float) for a in axes}
    up = {a: np.asarray(upper[a], dtype=float) for a in axes}
    # does step i's end meet step i+1's start on every axis?
    meets = np.ones(max(n - 1, 0), dtype=bool)
    for a in axes:
        meets &= np.abs(up[a][:-1] - low[a][1:]) <= SAME_PLACE * (
            1 + np.abs(low[a][1:])
        )
    has_lower = np.concatenate([[True], ~meets])
    per = 2 + has_lower.astype(np.int64)
    offsets = np.concatenate([[0], np.cumsum(per)[:-1]])
    size = int(per.sum())
    lower_at = offsets[has_lower]
    mid_at = offsets + has_lower
    up_at = mid_at + 1
    steps = np.arange(start, start + n, dtype=np.int64)

    out_pos = {}
    for a in axes:
        p = np.empty(size)
        p[lower_at] = low[a][has_lower]
        p[mid_at] = mid[a]
        p[up_at] = up[a]
        out_pos[a] = p

    times = np.empty(size, dtype=np.int64)
    half = total_us // 2
    times[mid_at] = half
    times[up_at] = total_us - half
    # the run-up, then the turnarounds
    gap_time = np.full(int(has_lower.sum()), 2.0 * accel)
    gaps = np.flatnonzero(has_lower)[1:]
    if len(gaps):
        travel = np.zeros(len(gaps))
        for a in axes:
            distance = np.abs(low[a][gaps] - up[a][gaps - 1])
            travel = np.maximum(travel, distance / max(velocity[a], 1e-9))
        gap_time[1:] += travel
    gap_time[0] = accel
    times[lower_at] = np.maximum(_whole_us(gap_time), 1)

    indices = np.full(size, -1, dtype=np.int64)
    indices[lower_at] = steps[has_lower]
    # a step that starts where the last ended is triggered at that end
    indices[up_at[:-1][meets]] = steps[1:][meets]
    point_of = np.full(size, -1, dtype=np.int64)
    point_of[mid_at] = steps
    done_after = np.full(size, start, dtype=np.int64)
    done_after[up_at] = steps + 1
    done_after = np.maximum.accumulate(done_after)

    run_up = {}
    for a in axes:
        speed = (up[a][0] - low[a][0]) / duration[0]
        run_up[a] = float(low[a][0] - speed * accel / 2)
    if times.max() > np.iinfo(np.int32).max:
        raise ProfileError("a profile time is over 2147 s")
    return Profile(
        start,
        start + n,
        out_pos,
        times.astype(np.int32),
        indices.astype(np.int32),
        point_of.astype(np.int32),
        done_after.astype(np.int32),
        run_up,
        mid,
    )

"""Scans for the runnable machines: small CompoundGenerators, with valid and
invalid axesToMove and breakpoints, and where each run of them ends."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from hypothesis import strategies as st

STEP_TIME = 0.001  # seconds per scan point


def line(axis: str, size: int) -> dict[str, Any]:
    """A LineGenerator dict of ``size`` points along ``axis``."""
    return {
        "typeid": "scanpointgenerator:generator/LineGenerator:1.0",
        "axes": [axis],
        "units": ["mm"],
        "start": [0.0],
        "stop": [1.0],
        "size": size,
        "alternate": False,
    }


@dataclass(frozen=True)
class Scan:
    """configure()'s arguments, whether they are valid, and the scan's shape."""

    params: dict[str, Any]
    valid: bool
    total: int
    boundaries: tuple[int, ...]  # where runs end: multiples of a run, breakpoints

    def next_end(self, completed: int) -> int:
        """Where a run starting at ``completed`` ends (total once done)."""
        return min([b for b in self.boundaries if b > completed] or [self.total])

    def __repr__(self) -> str:  # short, for hypothesis' step printout
        return f"Scan({self.params!r}, valid={self.valid})"


@st.composite
def scans(draw: st.DrawFn, valid_only: bool = False) -> Scan:
    """1 to 6 points in one or two dimensions (y outside x), random
    axesToMove (omitted, valid or not) and breakpoints (none, valid or not)."""
    if draw(st.booleans()):
        sizes = [draw(st.integers(1, 6))]
    else:
        outer = draw(st.integers(1, 3))
        sizes = [outer, draw(st.integers(1, 6 // outer))]
    axes = ["y", "x"][-len(sizes) :]
    total = math.prod(sizes)
    params: dict[str, Any] = {
        "generator": {
            "typeid": "scanpointgenerator:generator/CompoundGenerator:1.0",
            "generators": [line(a, n) for a, n in zip(axes, sizes)],
            "excluders": [],
            "mutators": [],
            "duration": STEP_TIME,
        }
    }
    valid = True
    bad = [] if valid_only else ["invalid"]
    how = draw(st.sampled_from(["omit", "valid", "valid", *bad]))
    if how == "omit":
        per_run = total  # no axesToMove: the whole scan in one run
    elif how == "valid":
        inner = draw(st.integers(0, len(sizes)))  # move the inner `inner` dims
        moving = axes[len(axes) - inner :]
        params["axesToMove"] = draw(st.permutations(moving))
        per_run = math.prod(sizes[len(sizes) - inner :])
    else:
        valid = False
        per_run = total
        params["axesToMove"] = ["y"] if len(sizes) == 2 else ["z"]
    ends: list[int] = []
    how = draw(st.sampled_from(["omit", "omit", "valid", *bad]))
    if how == "valid":
        cuts = draw(st.sets(st.integers(1, total - 1))) if total > 1 else set()
        ends = sorted(cuts) + [total]
        params["breakpoints"] = [b - a for a, b in zip([0, *ends], ends)]
    elif how == "invalid":
        valid = False
        params["breakpoints"] = [total + draw(st.integers(1, 3))]
    boundaries = set(range(per_run, total + 1, per_run)) | set(ends) | {total}
    return Scan(params, valid, total, tuple(sorted(boundaries)))

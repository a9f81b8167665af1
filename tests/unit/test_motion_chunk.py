"""MotionTrajectoryPart computes a scan's points once between its check of
the scan (validate) and the profile of its run (configure)."""

from __future__ import annotations

import numpy as np

from malcolm.parts.motion_manager import MotionTrajectoryPart
from malcolm.scan import gda, scan_points


def spiral(duration: float) -> dict:
    return gda.compound(gda.spiral("x", "y", 0.3, scale=0.01), duration=duration)


def test_the_profile_takes_the_chunk_the_check_computed():
    part = MotionTrajectoryPart()
    points = scan_points(spiral(0.1))
    limits = {"x": (1e6, -1e6, 1e6), "y": (1e6, -1e6, 1e6)}
    part._check_points(points, ["x", "y"], limits)
    # the same scan planned again (another copy, the same content)
    again = scan_points(spiral(0.1))
    assert again is not points and again.content == points.content
    chunk = part._chunk(again, 0, again.size, ["x", "y"])
    assert chunk is part._checked_chunk[1]
    fresh = again.chunk(0, again.size, ["x", "y"])
    for axis in ("x", "y"):
        assert np.array_equal(chunk.positions[axis], fresh.positions[axis])
        assert np.array_equal(chunk.lower[axis], fresh.lower[axis])
    assert np.array_equal(chunk.duration, fresh.duration)
    # other steps, or another scan, are computed
    assert part._chunk(again, 1, again.size, ["x", "y"]) is not chunk
    other = scan_points(spiral(0.2))
    other_chunk = part._chunk(other, 0, other.size, ["x", "y"])
    assert other_chunk is not chunk
    assert float(other_chunk.duration[0]) == 0.2

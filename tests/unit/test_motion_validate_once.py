"""MotionTrajectoryPart.validate checks a scan's points once per content and
limits: a beamline's validate and then its configure of the motion manager
hand it the same scan, which is not checked again; a new scan, or new
limits, are."""

from __future__ import annotations

import asyncio
from types import SimpleNamespace
from typing import Any

import pytest

from malcolm.core import BadValueError
from malcolm.parts.motion_manager import MotionTrajectoryPart
from malcolm.scan import gda, scan_points


class Motors:
    """What validate reads of the motor blocks: maxVelocity and limits."""

    def __init__(self) -> None:
        self.fields = {"maxVelocity": 1000.0, "lowLimit": -100.0, "highLimit": 100.0}

    def get_block(self, mri: str) -> dict[str, Any]:
        return {k: SimpleNamespace(value=v) for k, v in self.fields.items()}


def make_part(motors: Motors) -> tuple[MotionTrajectoryPart, list[int]]:
    part = MotionTrajectoryPart()
    part.controller = SimpleNamespace(mri="BL:MOTORS", process=motors)
    part.axes = {"x": ("A", "BL:MOTORS:a"), "y": ("B", "BL:MOTORS:b")}
    checks: list[int] = []
    real = part._check_points

    def counted(points: Any, moved: Any, limits: Any) -> None:
        checks.append(points.size)
        real(points, moved, limits)

    part._check_points = counted  # type: ignore[method-assign]
    return part, checks


def validate(part: MotionTrajectoryPart, generator: dict[str, Any]) -> Any:
    device = SimpleNamespace(
        params={"generator": generator},
        points=scan_points(generator),  # a new ScanPoints each time, as a plan
    )
    return asyncio.run(part.validate(None, device))


def spiral(duration: float = 0.01) -> dict[str, Any]:
    return gda.compound(gda.spiral("x", "y", 0.5, scale=0.01), duration=duration)


def test_the_same_scan_and_limits_are_checked_once():
    motors = Motors()
    part, checks = make_part(motors)
    validate(part, spiral())
    validate(part, spiral())  # the same content: not checked again
    assert len(checks) == 1 and checks[0] > 1000  # checked in a worker thread
    validate(part, spiral(0.02))  # another scan
    assert len(checks) == 2
    motors.fields["highLimit"] = 50.0  # other limits: checked again
    validate(part, spiral(0.02))
    assert len(checks) == 3


def test_a_refused_scan_is_refused_every_time():
    motors = Motors()
    part, checks = make_part(motors)
    motors.fields["maxVelocity"] = 0.01
    small = gda.compound(gda.line("x", 5, 0.0, 1.0), duration=0.01)
    for _ in range(2):
        with pytest.raises(BadValueError, match="maximum velocity"):
            validate(part, small)
    assert checks == [5, 5]
    motors.fields["maxVelocity"] = 1000.0  # now it can
    validate(part, small)
    validate(part, small)
    assert checks == [5, 5, 5]

"""SimMotorPart: a motor that moves at a set velocity; a put completes on arrival."""

from __future__ import annotations

import asyncio
import math
from typing import Any

from malcolm.core import Attribute, BadValueError, BooleanMeta, NumberMeta

from ..base import Part, PartRegistrar

TICK = 0.01


def velocity_problem(value: Any) -> str | None:
    """Why ``value`` cannot be a velocity (a positive, finite number), or None."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return f"must be a number of units/s, not {value!r}"
    if not math.isfinite(value) or value <= 0:
        return f"must be a positive, finite number of units/s, not {value!r}"
    return None


class SimMotorPart(Part):
    """Adds ``demand`` (put = move, done on arrival), ``position``, ``velocity``.

    A velocity that is not a positive, finite number, or a demand that is not
    finite, is refused at the put (a BadValueError naming the attribute) and
    changes nothing; a motor made with such a velocity is refused at once.
    """

    def __init__(self, name: str = "motor", velocity: float = 100.0) -> None:
        problem = velocity_problem(velocity)
        if problem is not None:
            raise ValueError(f"velocity {problem}")
        super().__init__(name)
        self.initial_velocity = velocity

    def setup(self, registrar: PartRegistrar) -> None:
        self.position = registrar.add_attribute(
            "position", NumberMeta("float64", "Readback position"), 0.0
        )
        self.demand = registrar.add_attribute(
            "demand", NumberMeta("float64", "Where to move to"), 0.0, put=self.move
        )
        self.velocity = registrar.add_attribute(
            "velocity",
            NumberMeta("float64", "Speed in units/s", writeable=True),
            self.initial_velocity,
            put=self.set_velocity,
        )
        self.moving = registrar.add_attribute(
            "moving", BooleanMeta("Whether it is moving"), False
        )

    def set_velocity(self, value: float) -> None:
        """Take a new speed; the move under way uses it from its next tick."""
        _refuse(self.velocity, velocity_problem(value))
        self.velocity.set_value(value)

    async def move(self, target: float) -> None:
        if not math.isfinite(target):
            _refuse(self.demand, f"must be a finite position, not {target!r}")
        self.demand.set_value(target)
        self.moving.set_value(True)
        try:
            while self.position.value != target:
                step = self.velocity.value * TICK
                here = self.position.value
                if abs(target - here) <= step:
                    here = target
                else:
                    here += step if target > here else -step
                self.position.set_value(here)
                if here != target:
                    await asyncio.sleep(TICK)
        finally:
            self.moving.set_value(False)


def _refuse(attr: Attribute, problem: str | None) -> None:
    if problem is not None:
        raise BadValueError(f"{attr.path_name}: {problem}")

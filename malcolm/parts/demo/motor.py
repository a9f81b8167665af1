"""SimMotorPart: a motor that moves at a set velocity; a put completes on arrival."""

from __future__ import annotations

import asyncio

from malcolm.core import BooleanMeta, NumberMeta

from ..base import Part, PartRegistrar

TICK = 0.01


class SimMotorPart(Part):
    """Adds ``demand`` (put = move, done on arrival), ``position``, ``velocity``."""

    def __init__(self, name: str = "motor", velocity: float = 100.0) -> None:
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
        )
        self.moving = registrar.add_attribute(
            "moving", BooleanMeta("Whether it is moving"), False
        )

    async def move(self, target: float) -> None:
        self.demand.set_value(target)
        self.moving.set_value(True)
        try:
            while self.position.value != target:
                step = max(self.velocity.value, 1e-9) * TICK
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

"""SimDetectorPart: a detector that takes the scan's duration per point."""

from __future__ import annotations

from typing import Any

from malcolm.core import NumberMeta
from malcolm.fsm import RunnableDevice
from malcolm.hooks import Task

from ..base import Part, PartRegistrar
from ..pacing import Deadlines
from .steps import run_steps


class SimDetectorPart(Part):
    """Counts frames: one per point, each taking the point's duration (or
    ``default_exposure`` if the scan gives none), paced against the run's
    deadlines (:class:`~malcolm.parts.pacing.Deadlines`)."""

    def __init__(self, name: str = "detector", default_exposure: float = 0.01):
        super().__init__(name)
        self.default_exposure = default_exposure

    def setup(self, registrar: PartRegistrar) -> None:
        self.frames = registrar.add_attribute(
            "framesTaken", NumberMeta("int32", "Frames taken in this scan"), 0
        )

    @RunnableDevice.Configure
    async def configure(self, task: Task, device: Any) -> None:
        self.frames.set_value(0)

    @RunnableDevice.Run
    async def run(self, task: Task, device: Any) -> None:
        steps = run_steps(device.points, device.completedSteps, device.configuredSteps)
        deadlines = Deadlines()
        for step, _, duration in steps:
            d = duration if duration is not None and duration > 0 else None
            await deadlines.wait(d or self.default_exposure)
            self.frames.set_value(self.frames.value + 1)
            task.report_progress(step + 1)

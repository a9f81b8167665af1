"""SimDetectorPart: a detector that takes the scan's duration per point."""

from __future__ import annotations

from typing import Any

from malcolm.core import NumberMeta
from malcolm.fsm import RunnableDevice
from malcolm.hooks import Task

from ..base import Part, PartRegistrar
from ..pacing import Deadlines


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
        points = device.points
        durations = points.duration
        deadlines = Deadlines()
        for step in range(device.completedSteps, device.configuredSteps):
            d = self.default_exposure
            if durations is not None and float(durations[step]) > 0:
                d = float(durations[step])
            await deadlines.wait(d)
            self.frames.set_value(self.frames.value + 1)
            task.report_progress(step + 1)

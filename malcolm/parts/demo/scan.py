"""Parts for a scan block that coordinates runnable children and motors."""

from __future__ import annotations

import asyncio
from typing import Any

from malcolm.fsm import RunnableDevice
from malcolm.hooks import Task

from ..base import ChildPart


class RunnableChildPart(ChildPart):
    """Drives a runnable child block (e.g. a detector) through the scan."""

    @RunnableDevice.Configure
    async def configure(self, task: Task, device: Any) -> None:
        child = self.child
        if child.state.value in ("Fault", "Aborted", "Armed"):
            await task.process.post([self.mri, "reset"])
        params = {
            k: device.params[k]
            for k in ("generator", "axesToMove", "breakpoints")
            if k in device.params
        }
        await task.process.post([self.mri, "configure"], params)

    @RunnableDevice.Run
    async def run(self, task: Task, device: Any) -> None:
        sid = task.subscribe(self.child.completedSteps, task.report_progress)
        try:
            await task.process.post([self.mri, "run"])
        finally:
            task.unsubscribe(sid)

    @RunnableDevice.Seek
    async def seek(self, task: Task, device: Any) -> None:
        state = self.child.state.value
        if state in ("Armed", "Paused", "Running", "Finished"):
            await task.process.post(
                [self.mri, "pause"], {"lastGoodStep": device.completedSteps}
            )

    @RunnableDevice.Abort
    async def abort(self, task: Task, device: Any) -> None:
        if self.child.state.value not in ("Aborted", "Fault", "Disabled", "Ready"):
            await task.process.post([self.mri, "abort"])

    @RunnableDevice.Reset
    async def reset(self, task: Task, device: Any) -> None:
        if self.child.state.value in ("Fault", "Aborted", "Armed", "Finished"):
            await task.process.post([self.mri, "reset"])


class MotorMovePart(ChildPart):
    """Moves a motor block along one axis of the scan, point by point."""

    def __init__(self, name: str, mri: str, axis: str) -> None:
        super().__init__(name, mri)
        self.axis = axis

    def _position(self, device: Any, step: int) -> float | None:
        points = device.points
        if points is None or self.axis not in points.positions:
            return None
        return float(points.positions[self.axis][step])

    @RunnableDevice.Configure
    async def configure(self, task: Task, device: Any) -> None:
        where = self._position(device, 0)
        if where is not None:
            await task.put(self.child.demand, where)

    @RunnableDevice.Run
    async def run(self, task: Task, device: Any) -> None:
        durations = device.points.duration
        for step in range(device.completedSteps, device.configuredSteps):
            where = self._position(device, step)
            if where is not None:
                await task.put(self.child.demand, where)
            if durations is not None:
                await asyncio.sleep(float(durations[step]))
            task.report_progress(step + 1)

    @RunnableDevice.Seek
    async def seek(self, task: Task, device: Any) -> None:
        if device.completedSteps < device.totalSteps:
            where = self._position(device, device.completedSteps)
            if where is not None:
                await task.put(self.child.demand, where)

"""Parts for a scan block that coordinates runnable children and motors.

They decide what to call on a child from its methods' ``writeable`` flags
(which every transport shows), never from its state's name.
"""

from __future__ import annotations

import asyncio
from typing import Any

from malcolm.core import NotAllowedError
from malcolm.fsm import RunnableDevice
from malcolm.hooks import Task

from ..base import ChildPart
from ..pacing import Deadlines
from .steps import run_steps


def _retrieve(fut: asyncio.Future[Any]) -> None:
    if not fut.cancelled():
        fut.exception()  # its error reaches whoever awaits it, or nobody


class RunnableChildPart(ChildPart):
    """Drives a runnable child block (e.g. a detector) through the scan.

    The child's ``run()`` is called in a future the part keeps: when the
    scan pauses, the run phase is cancelled but the child's run goes on
    until the Seek phase pauses the child too; on resume the part resumes
    the child and waits for that same run.
    """

    def __init__(self, name: str, mri: str) -> None:
        super().__init__(name, mri)
        self._child_run: asyncio.Future[Any] | None = None

    def allowed(self, task: Task, method: str) -> bool:
        """Whether the child's ``method`` may be called now."""
        try:
            return bool(task.process.get([self.mri, method, "meta", "writeable"]))
        except LookupError:
            return False

    def _pending_run(self) -> asyncio.Future[Any] | None:
        run = self._child_run
        return run if run is not None and not run.done() else None

    @RunnableDevice.Configure
    async def configure(self, task: Task, device: Any) -> None:
        if not self.allowed(task, "configure") and self.allowed(task, "reset"):
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
            pending = self._pending_run()
            if pending is not None and self.allowed(task, "resume"):
                await task.process.post([self.mri, "resume"])
            elif pending is None:
                if not self.allowed(task, "run"):
                    raise NotAllowedError(
                        f"{self.name}: {self.mri} can neither run nor resume now"
                    )
                pending = asyncio.ensure_future(task.process.post([self.mri, "run"]))
                pending.add_done_callback(_retrieve)
                self._child_run = pending
            # shielded: a pause cancels this phase, not the child's run
            await asyncio.shield(pending)
        finally:
            task.unsubscribe(sid)

    @RunnableDevice.Seek
    async def seek(self, task: Task, device: Any) -> None:
        pending = self._pending_run()
        if pending is not None and not self.allowed(task, "pause"):
            # the child is finishing its run (it cannot pause there): let it
            await asyncio.shield(pending)
        if self.allowed(task, "pause"):
            await task.process.post(
                [self.mri, "pause"], {"lastGoodStep": device.completedSteps}
            )

    @RunnableDevice.Abort
    async def abort(self, task: Task, device: Any) -> None:
        if self.allowed(task, "abort") and not self.allowed(task, "configure"):
            await task.process.post([self.mri, "abort"])

    @RunnableDevice.Reset
    async def reset(self, task: Task, device: Any) -> None:
        if self.allowed(task, "reset"):
            await task.process.post([self.mri, "reset"])


class MotorMovePart(ChildPart):
    """Moves a motor block along one axis of the scan, point by point: to each
    point's position, then on at the point's deadline (the run's start plus
    the durations so far, :class:`~malcolm.parts.pacing.Deadlines`)."""

    def __init__(self, name: str, mri: str, axis: str) -> None:
        super().__init__(name, mri)
        self.axis = axis

    def _position(self, device: Any, step: int) -> float | None:
        points = device.points
        if points is None or self.axis not in points.axes:
            return None
        return points.position(self.axis, step)  # one step, not the whole scan

    @RunnableDevice.Configure
    async def configure(self, task: Task, device: Any) -> None:
        where = self._position(device, 0)
        if where is not None:
            await task.put(self.child.demand, where)

    @RunnableDevice.Run
    async def run(self, task: Task, device: Any) -> None:
        steps = run_steps(
            device.points, device.completedSteps, device.configuredSteps, self.axis
        )
        deadlines = Deadlines()
        for step, where, duration in steps:
            if where is not None:
                await task.put(self.child.demand, where)
            if duration is not None:
                await deadlines.wait(duration)
            task.report_progress(step + 1)

    @RunnableDevice.Seek
    async def seek(self, task: Task, device: Any) -> None:
        if device.completedSteps < device.totalSteps:
            where = self._position(device, device.completedSteps)
            if where is not None:
                await task.put(self.child.demand, where)

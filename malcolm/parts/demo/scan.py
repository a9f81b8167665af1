"""Parts for a scan block that coordinates runnable children and motors.

They decide what to call on a child from its methods' ``writeable`` flags
(which every transport shows), never from its state's name.
"""

from __future__ import annotations

import asyncio
from collections.abc import Mapping
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

    The manager's Validate asks the child's ``validate()`` (its refusal
    refuses the manager's configure); Reset and Disable bring the child back
    to where its next call is allowed, whatever the scan left it doing: on
    reset it is aborted if it is in the middle of a scan, then reset; on
    disable it is disabled.
    """

    #: the configure parameters passed on to the child
    PARAMS = ("generator", "axesToMove", "breakpoints")

    def __init__(self, name: str, mri: str) -> None:
        super().__init__(name, mri)
        self._child_run: asyncio.Future[Any] | None = None

    def allowed(self, task: Task, method: str) -> bool:
        """Whether the child's ``method`` may be called now."""
        try:
            return bool(task.process.get([self.mri, method, "meta", "writeable"]))
        except LookupError:
            return False

    def mid_scan(self, task: Task) -> bool:
        """Whether the child is in the middle of a scan (running, paused,
        seeking...): it may abort, but may be neither configured nor reset."""
        return self.allowed(task, "abort") and not (
            self.allowed(task, "configure") or self.allowed(task, "reset")
        )

    def _pending_run(self) -> asyncio.Future[Any] | None:
        run = self._child_run
        return run if run is not None and not run.done() else None

    def _child_params(self, device: Any) -> dict[str, Any]:
        return {k: device.params[k] for k in self.PARAMS if k in device.params}

    async def _post(self, task: Task, method: str, params: Any = None) -> Any:
        return await task.process.post([self.mri, method], params)

    @RunnableDevice.Validate
    async def validate(self, task: Task, device: Any) -> dict[str, Any]:
        """The child checks the parameters: its refusal refuses the manager's
        configure (or validate); returns the parameters it changed. A child
        that cannot validate now (e.g. in Fault, which Configure resets)
        checks them when it is configured."""
        if not self.allowed(task, "validate"):
            return {}
        params = self._child_params(device)
        checked = await self._post(task, "validate", params)
        return {
            k: v
            for k, v in (checked or {}).items()
            if k in params and not same_value(v, params[k])
        }

    @RunnableDevice.Configure
    async def configure(self, task: Task, device: Any) -> None:
        self._child_run = None  # a new scan never continues an old run
        if not self.allowed(task, "configure") and self.allowed(task, "reset"):
            await self._post(task, "reset")  # e.g. Aborted or Fault
        await self._post(task, "configure", self._child_params(device))

    @RunnableDevice.Run
    async def run(self, task: Task, device: Any) -> None:
        sid = task.subscribe(self.child.completedSteps, task.report_progress)
        try:
            pending = self._pending_run()
            if pending is not None and self.allowed(task, "resume"):
                await self._post(task, "resume")
            elif pending is None:
                if not self.allowed(task, "run"):
                    raise NotAllowedError(
                        f"{self.name}: {self.mri} can neither run nor resume now"
                    )
                pending = asyncio.ensure_future(self._post(task, "run"))
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
            await self._post(task, "pause", {"lastGoodStep": device.completedSteps})

    @RunnableDevice.Abort
    async def abort(self, task: Task, device: Any) -> None:
        self._child_run = None
        if self.allowed(task, "abort") and not self.allowed(task, "configure"):
            await self._post(task, "abort")

    @RunnableDevice.Reset
    async def reset(self, task: Task, device: Any) -> None:
        """Back to Ready, from wherever a fault, a disable or someone else
        left the child: abort it if it is in the middle of a scan, then
        reset it if it may be."""
        self._child_run = None
        if self.mid_scan(task):
            await self._post(task, "abort")
        if self.allowed(task, "reset"):
            await self._post(task, "reset")

    @RunnableDevice.Disable
    async def disable(self, task: Task, device: Any) -> None:
        """The manager lets go of its hardware: so does the child (its run,
        running or paused, ends); the manager's reset resets it."""
        self._child_run = None
        if self.allowed(task, "disable"):
            await self._post(task, "disable")


def same_value(a: Any, b: Any) -> bool:
    """Whether two parameter values are the same: containers element by
    element, arrays by their elements (they have no plain ``==``)."""
    if a is b:
        return True
    if isinstance(a, Mapping) and isinstance(b, Mapping):
        return a.keys() == b.keys() and all(same_value(a[k], b[k]) for k in a)
    if hasattr(a, "tolist") or hasattr(b, "tolist"):  # numpy arrays and scalars
        a = a.tolist() if hasattr(a, "tolist") else a
        b = b.tolist() if hasattr(b, "tolist") else b
    if isinstance(a, list | tuple) and isinstance(b, list | tuple):
        return len(a) == len(b) and all(same_value(x, y) for x, y in zip(a, b))
    try:
        return bool(a == b)
    except (TypeError, ValueError):
        return False


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

"""RunnableController: configure / run / pause / seek / resume / abort over a scan.

Step maths lives here; the order of work lives in the model. A run does
the steps of the innermost dimensions in ``axesToMove`` (cut short at the
next breakpoint) and ends Armed, or Finished after the last step.
"""

from __future__ import annotations

import asyncio
from collections.abc import Mapping
from itertools import accumulate
from typing import Any

from malcolm.core import (
    AbortedError,
    BadValueError,
    MalcolmError,
    MapMeta,
    Meta,
    MethodMeta,
    NotAllowedError,
    NumberArrayMeta,
    NumberMeta,
    StringArrayMeta,
)
from malcolm.core.generator import GeneratorMeta
from malcolm.scan import ScanPoints, scan_points
from malcolm.scan.errors import GeneratorError

from .base import Device
from .manager import ManagerController

MAX_VALIDATE_ROUNDS = 10


class RunnableController(ManagerController):
    """Interprets the ``runnable_device`` model (and models that extend it)."""

    model_name = "runnable_device"

    def setup_fields(self) -> None:
        super().setup_fields()
        self.completed = self._add_attr(
            "completedSteps",
            NumberMeta("int32", "Steps of the scan done", writeable=True),
        )
        self.configured = self._add_attr(
            "configuredSteps", NumberMeta("int32", "Steps the hardware is set up for")
        )
        self.total = self._add_attr(
            "totalSteps", NumberMeta("int32", "Steps in the whole scan")
        )
        self.simultaneous_axes = self._add_attr(
            "simultaneousAxes",
            StringArrayMeta("Axes that may move together in a run", writeable=True),
        )
        self._configure_takes: dict[str, Meta] = {
            "generator": GeneratorMeta("The scan to do", writeable=True),
            "axesToMove": StringArrayMeta(
                "Axes a single run moves (the inner ones)", writeable=True
            ),
            "breakpoints": NumberArrayMeta(
                "int32", "Run lengths the scan is cut into", writeable=True
            ),
        }
        self._configure_required = ["generator"]
        self._configure_defaults: dict[str, Any] = {"breakpoints": ()}
        self.points: ScanPoints | None = None
        self._steps_per_run = 1
        self._breakpoint_ends: list[int] = []
        self._progress: dict[str, int] = {}
        self._paused = False
        self._run_inner: asyncio.Task[Any] | None = None
        self._resume: asyncio.Future[bool] | None = None
        self._seek_op: asyncio.Task[Any] | None = None

    # ---- configure arguments (parts add their own)
    def add_configure_arg(
        self, name: str, meta: Meta, default: Any, required: bool
    ) -> None:
        if name in self._configure_takes:
            raise ValueError(f"{self.mri}: configure already takes {name!r}")
        meta.writeable = True
        self._configure_takes[name] = meta
        if required:
            self._configure_required.append(name)
        elif default is not None:
            self._configure_defaults[name] = default
        for call in ("configure", "validate"):
            if call in self.block:
                self.block.remove(call)
                self.add_call(call)

    def remove_configure_arg(self, name: str) -> None:
        if name in self._configure_takes:
            del self._configure_takes[name]
            self._configure_defaults.pop(name, None)
            if name in self._configure_required:
                self._configure_required.remove(name)
            for call in ("configure", "validate"):
                if call in self.block:
                    self.block.remove(call)
                    self.add_call(call)

    def _configure_meta(self, description: str, returns: bool) -> MethodMeta:
        takes = MapMeta(dict(self._configure_takes), list(self._configure_required))
        return MethodMeta(
            takes,
            MapMeta(dict(self._configure_takes)) if returns else MapMeta(),
            dict(self._configure_defaults),
            description=description,
        )

    def method_meta_configure(self) -> MethodMeta:
        return self._configure_meta("Validate the parameters, set up the scan", False)

    def method_meta_validate(self) -> MethodMeta:
        return self._configure_meta("Check parameters; returns them as tweaked", True)

    # ---- guards named in the model
    def scan_complete(self) -> bool:
        return self.completed.value >= self.total.value

    def is_paused(self) -> bool:
        return self._paused

    # ---- step maths
    def next_configured(self, completed: int) -> int:
        total = self.total.value
        spr = max(1, self._steps_per_run)
        end = min(total, (completed // spr + 1) * spr)
        for b in self._breakpoint_ends:
            if b > completed:
                end = min(end, b)
                break
        return end

    def _prepare(self, params: Mapping[str, Any], device: Device | None = None) -> None:
        """Check the scan; set it up, or only on ``device`` (for validate)."""
        generator = params["generator"]
        points = generator if isinstance(generator, ScanPoints) else None
        try:
            points = points or scan_points(generator)
            axes = params.get("axesToMove")
            if axes is None or "axesToMove" not in params:
                axes = self.simultaneous_axes.value or None
            spr = points.steps_per_run(list(axes) if axes is not None else None)
        except (GeneratorError, ValueError) as e:
            raise BadValueError(f"{self.mri}.configure: {e}") from None
        breakpoints = [int(b) for b in params.get("breakpoints") or ()]
        if breakpoints and sum(breakpoints) != points.size:
            raise BadValueError(
                f"{self.mri}.configure.breakpoints: they add up to {sum(breakpoints)}"
                f" but the scan has {points.size} points"
            )
        if any(b <= 0 for b in breakpoints):
            raise BadValueError(f"{self.mri}.configure.breakpoints: must be positive")
        if device is None:
            device = self.device
            self.points = points
            self._steps_per_run = spr
            self._breakpoint_ends = list(accumulate(breakpoints))
        device.points = points
        device.params = dict(params)

    # ---- phases: the controller's part of each
    async def run_phase(
        self, phase: str, device: Device | None = None
    ) -> dict[str, Any]:
        device = device or self.device
        if phase != "Validate":
            return await super().run_phase(phase, device)
        for _ in range(MAX_VALIDATE_ROUNDS):
            results = await super().run_phase(phase, device)
            changed = {}
            for part, tweaks in results.items():
                if not tweaks:
                    continue
                if not isinstance(tweaks, Mapping):
                    raise BadValueError(
                        f"{self.mri}: part {part!r} returned {tweaks!r} from"
                        " Validate; expected a dict of changed parameters"
                    )
                for k, v in tweaks.items():
                    if device.params.get(k) != v:
                        changed[k] = v
            if not changed:
                return results
            device.params.update(changed)
        raise BadValueError(
            f"{self.mri}: parameters did not settle after {MAX_VALIDATE_ROUNDS}"
            " validate rounds"
        )

    async def before_phase(self, phase: str) -> None:
        if phase == "PreConfigure":
            self._paused = False
            self.total.set_value(self.points.size if self.points else 0)
            self.completed.set_value(0)
            self.configured.set_value(self.next_configured(0))
        elif phase == "PreRun":
            # every part with a hook in the run's phases reports progress
            run = self.model.transitions_for("done", "Running")
            phases = {ph for t in run for ph in t.phases}
            start = self.completed.value
            self._progress = {
                h.part: start for ph in phases for h in self.hooks.get(ph, ())
            }
            self.device.stepsToDo = self.configured.value - self.completed.value
        elif phase == "PostRunArmed":
            self.configured.set_value(self.next_configured(self.completed.value))

    def move(self, trigger: str, dest: str | None = None) -> None:
        leaving = self.current
        super().move(trigger, dest)
        if leaving == "Running" and self.current == "PostRun":
            self.completed.set_value(self.configured.value)

    def _on_progress(self, part: str, steps: int) -> None:
        if self.current != "Running":
            return
        if part not in self._progress:
            return
        self._progress[part] = steps
        done = min(self._progress.values())
        if self.completed.value < done <= self.configured.value:
            self.completed.set_value(done)

    # ---- calls
    async def do_validate(self, **params: Any) -> dict[str, Any]:
        """Check parameters; returns them as the parts would tweak them."""
        # on a device of its own: validating must not touch the armed scan
        device = Device(self)
        self._prepare(params, device)
        await self.run_phase("Validate", device)
        return dict(device.params)

    async def do_configure(self, **params: Any) -> None:
        """Validate the parameters and set up the scan; ends Armed."""

        async def configure() -> None:
            self._prepare(params)
            await self.fire("configure")
            await self.settle()

        await self.operation("configure", configure())

    async def do_run(self) -> None:
        """Do the next run of steps; ends Armed, or Finished after the last."""
        await self.operation("run", self._run())

    async def _run(self) -> None:
        await self.fire("run")
        while True:
            self._run_inner = asyncio.ensure_future(self.settle())
            try:
                await self._run_inner
                return
            except asyncio.CancelledError:
                me = asyncio.current_task()
                if (me is not None and me.cancelling()) or not self._paused:
                    raise
            # paused: wait for resume (or abort, which cancels this task)
            loop = asyncio.get_running_loop()
            self._resume = loop.create_future()
            await self._resume

    async def do_pause(
        self, lastGoodStep: int | None = None, completedSteps: int | None = None
    ) -> None:
        """Go back to a step; from Running land Paused, otherwise Armed."""
        steps = lastGoodStep if lastGoodStep is not None else completedSteps
        if steps is None:
            steps = self.completed.value
        steps = max(0, min(int(steps), self.total.value))
        self._check_not_seeking("pause")
        if self._claim is not None:
            raise NotAllowedError(
                f"{self.mri}: cannot pause while {self._claim_name} is in progress"
                f" (state {self.current})"
            )
        try:
            if self.current == "Running":
                inner = self._run_inner
                if inner is None or inner.done():
                    raise NotAllowedError(
                        f"{self.mri}: cannot pause a run that is not running yet"
                        f" (state {self.current})"
                    )
                self._paused = True
                self.choose("pause")
                inner.cancel()
                await asyncio.wait({inner})
                # what the cancelled run phase subscribed to goes with it
                for task in self.tasks.values():
                    task.stop()
                await self._seek("pause", steps)
            else:
                if self.current == "Armed" and self.busy_with() == "run":
                    raise NotAllowedError(
                        f"{self.mri}: cannot pause a run that is not running yet"
                        f" (state {self.current})"
                    )
                await self._seek("pause", steps)
        except (NotAllowedError, BadValueError, AbortedError):
            raise
        except Exception as e:
            await self.go_fault(e)
            raise

    def method_meta_pause(self) -> MethodMeta:
        step = "Last good step; the scan goes back to it"
        return MethodMeta(
            MapMeta(
                {
                    "lastGoodStep": NumberMeta("int32", step, writeable=True),
                    "completedSteps": NumberMeta("int32", step, writeable=True),
                }
            ),
            description="Pause: go back to lastGoodStep (alias completedSteps)",
        )

    async def put_completedSteps(self, steps: int) -> None:  # noqa: N802
        if not 0 <= steps <= self.total.value:
            raise BadValueError(
                f"{self.mri}.completedSteps: {steps} is outside [0, {self.total.value}]"
            )
        try:
            await self._seek("seek", steps)
        except (NotAllowedError, AbortedError):
            raise
        except Exception as e:
            await self.go_fault(e)
            raise

    async def _seek(self, trigger: str, steps: int) -> None:
        self.choose(trigger)  # fail early if not allowed here
        self._check_not_seeking(trigger)
        # beside a run only once it runs (or waits Paused); never beside an
        # abort or disable taking over, nor any other operation
        beside_run = self._op_name == "run" and self.current in ("Running", "Paused")
        busy = self.busy_with()
        if busy is not None and not (busy == "run" and beside_run):
            raise NotAllowedError(
                f"{self.mri}: cannot {trigger} while {busy} is in progress"
                f" (state {self.current})"
            )

        async def seek() -> None:
            await self.fire(trigger)  # the Pause phase (from Running) runs first
            # the target is known before Seeking chooses where to go next
            self._seek_to = None
            self.completed.set_value(steps)
            self.configured.set_value(self.next_configured(steps))
            await self.settle()

        # a task of its own, so that abort and disable can cancel it
        self._seek_op = op = asyncio.ensure_future(seek())
        await asyncio.wait({op})
        if op.cancelled():
            raise AbortedError(f"{self.mri}: {trigger} was aborted")
        op.result()

    def _check_not_seeking(self, name: str) -> None:
        if self._seek_op is not None and not self._seek_op.done():
            raise NotAllowedError(
                f"{self.mri}: cannot {name} while a pause or seek is in progress"
                f" (state {self.current})"
            )

    def side_operations(self) -> list[asyncio.Future[Any]]:
        return [f for f in (self._seek_op, self._run_inner) if f is not None]

    async def go_fault(self, error: BaseException | str) -> None:
        await super().go_fault(error)
        resume = self._resume
        if resume is not None and not resume.done():
            # a paused run() fails with the fault instead of waiting forever
            if not isinstance(error, BaseException):
                error = MalcolmError(error)
            resume.set_exception(error)

    async def do_resume(self) -> None:
        """Continue a paused scan."""
        self._check_not_seeking("resume")
        self._paused = False
        self.move("resume")
        if self._resume is not None and not self._resume.done():
            self._resume.set_result(True)

    async def do_abort(self) -> None:
        """Stop whatever is running; a pending run() fails. Ends Aborted."""

        async def abort() -> None:
            for task in self.tasks.values():
                task.stop()
            self._paused = False
            await self.fire("abort")
            await self.settle()

        await self.operation("abort", abort(), interrupt=True)

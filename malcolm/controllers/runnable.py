"""RunnableController: configure / run / pause / seek / resume / abort over a scan.

The order of work lives in the model; the step maths in :mod:`.scan_steps`;
what configure() takes in :mod:`.configure_args`. A run does the steps of
the innermost dimensions in ``axesToMove`` (cut short at the next
breakpoint) and ends Armed, or Finished after the last step.
"""

from __future__ import annotations

import asyncio
from collections.abc import Mapping
from dataclasses import replace
from typing import TYPE_CHECKING, Any

from malcolm.core import BadValueError, NumberMeta, StringArrayMeta
from malcolm.core.generator import GeneratorMeta
from malcolm.fsm import Transition
from malcolm.hooks import Hook

from .configure_args import ConfigureArgs, configure_generator_meta
from .device import Device
from .manager import ManagerController
from .pausing import PauseAndSeek
from .scan_steps import ScanPlan, plan_scan_off_loop
from .validated import CALLER, Validated

if TYPE_CHECKING:
    from malcolm.scan import ScanPoints

MAX_VALIDATE_ROUNDS = 10


class RunnableController(PauseAndSeek, ConfigureArgs, ManagerController):
    """Interprets the ``runnable_device`` model (and models that extend it).

    The controller's part of each move is found by the roles of the states
    it joins (never their names): ``configuring -> armed`` starts the scan's
    steps, ``running -> post_run`` is the run (progress is tracked while the
    block is ``running``), ``post_run -> armed`` sets up the next run.
    """

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
        self._init_configure_args(configure_generator_meta(GeneratorMeta))
        self.plan: ScanPlan | None = None
        self._paused = False
        self._run_inner: asyncio.Task[Any] | None = None
        self._resume: asyncio.Future[bool] | None = None
        self._seek_op: asyncio.Task[Any] | None = None
        # the last validate() that gave its arguments back unchanged inside
        # a manager's operation, and the device of a configure that needs
        # no Validate phase (validated.py)
        self._validated: Validated | None = None
        self._prevalidated: tuple[Device, dict[str, Any]] | None = None
        # progress of the run in progress: where it started, what each part
        # reported, and how many hooks of each part are still working
        self._run_start = 0
        self._reported: dict[str, int] = {}
        self._working: dict[str, int] = {}

    @property
    def points(self) -> ScanPoints | None:
        """The configured scan's points."""
        return self.plan.points if self.plan is not None else None

    # ---- guards named in the model
    def scan_complete(self) -> bool:
        return self.completed.value >= self.total.value

    def is_paused(self) -> bool:
        return self._paused

    # ---- step maths
    def next_configured(self, completed: int) -> int:
        """Where a run that starts at step ``completed`` stops."""
        return self.plan.next_configured(completed) if self.plan else 0

    def on_transition(self, t: Transition) -> None:
        super().on_transition(t)
        move = (self.role(t.source), self.role(t.dest))
        if move == ("configuring", "armed"):
            self._paused = False
            self.total.set_value(self.plan.total if self.plan else 0)
            self.completed.set_value(0)
            self.configured.set_value(self.next_configured(0))
        elif move == ("running", "post_run"):
            self._run_start = self.completed.value
            self._reported = {}
            self._working = {}
            self.device.stepsToDo = self.configured.value - self.completed.value
        elif move == ("post_run", "armed"):
            self.configured.set_value(self.next_configured(self.completed.value))

    def on_moved(self, t: Transition) -> None:
        if (self.role(t.source), self.role(t.dest)) == ("running", "post_run"):
            self._working = {}
            self.completed.set_value(self.configured.value)
        super().on_moved(t)

    # ---- phases
    async def run_phase(
        self, phase: str, device: Device | None = None
    ) -> dict[str, Any]:
        device = device or self.device
        if phase == self._validate_phase():
            return await self._validate_rounds(phase, device)
        if self.role() == "running":
            hooks = self._tracked(self.hooks_of(phase))
            return await self.run_hooks(phase, hooks, device)
        return await super().run_phase(phase, device)

    def _validate_phase(self) -> str | None:
        """The model's phase with the validate role (looked up once per
        model: a model is read-only)."""
        kept = self.__dict__.get("_validate_phase_of")
        if kept is None or kept[0] is not self.model:
            kept = (self.model, self.model.phase_for("validate"))
            self.__dict__["_validate_phase_of"] = kept
        return kept[1]

    async def _validate_rounds(self, phase: str, device: Device) -> dict[str, Any]:
        """Run the validate phase until no part changes the parameters; not
        at all for a configure whose arguments this block's validate() gave
        back unchanged inside the same operation of its caller (what the
        phase returned then is what it returns)."""
        prevalidated = self._prevalidated
        if prevalidated is not None and prevalidated[0] is device:
            self._prevalidated = None
            device.part_info[phase] = prevalidated[1]
            return prevalidated[1]
        for _ in range(MAX_VALIDATE_ROUNDS):
            results = await super().run_phase(phase, device)
            changed = {}
            for part, tweaks in results.items():
                if not tweaks:
                    continue
                if not isinstance(tweaks, Mapping):
                    raise BadValueError(
                        f"{self.mri}: part {part!r} returned {tweaks!r} from"
                        f" {phase}; expected a dict of changed parameters"
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

    # ---- progress: the slowest part still working
    def _tracked(self, hooks: list[Hook]) -> list[Hook]:
        """``hooks``, each telling the controller when it has returned."""
        loop = asyncio.get_running_loop()
        tracked = []
        for hook in hooks:
            self._working[hook.part] = self._working.get(hook.part, 0) + 1
            tracked.append(replace(hook, func=self._reporting(hook, loop)))
        return tracked

    def _reporting(self, hook: Hook, loop: asyncio.AbstractEventLoop) -> Any:
        func, part = hook.func, hook.part
        working = self._working  # this run's: a later run has its own
        if hook.is_async:

            async def returns(*args: Any) -> Any:
                result = await func(*args)
                self._hook_returned(part, working)
                return result

        else:

            def returns(*args: Any) -> Any:
                result = func(*args)
                loop.call_soon_threadsafe(self._hook_returned, part, working)
                return result

        return returns

    def _hook_returned(self, part: str, working: dict[str, int]) -> None:
        if working is not self._working or part not in working:
            return
        working[part] -= 1
        if working[part] <= 0:
            del working[part]
            self._show_progress()

    def _on_progress(self, part: str, steps: int) -> None:
        if self.role() != "running" or part not in self._working:
            return
        self._reported[part] = steps
        self._show_progress()

    def _show_progress(self) -> None:
        if not self._working:
            return
        done = overall_progress(
            {p: self._reported.get(p, self._run_start) for p in self._working}
        )
        if self.completed.value < done <= self.configured.value:
            self.completed.set_value(done)

    # ---- calls
    async def do_validate(self, **params: Any) -> dict[str, Any]:
        """Check parameters; returns them as the parts would tweak them.

        The scan's points are computed in a worker thread (the loop stays
        live), once, before anything runs; a scan that cannot be done is
        refused and changes nothing."""
        first = await self._plan(params)
        caller = CALLER.get()

        async def validate() -> dict[str, Any]:
            # on a device of its own: validating must not touch the armed scan
            device = self._device_for(params, first)
            phase = self._validate_phase()
            results: dict[str, Any] = {}
            if phase is not None:
                results = await self.run_phase(phase, device)
            if self._tweaked(device.params, params):
                await self._plan(device.params)
            elif caller is not None:  # a configure in the same call need not
                self._validated = Validated(caller, dict(params), results)
            return dict(device.params)

        return await self._planned_operation("validate", validate(), params, first)

    async def _planned_operation(
        self, name: str, coro: Any, params: Mapping[str, Any], plan: ScanPlan
    ) -> Any:
        """``operation(name, coro)``, in which the children the hooks call
        take the points of ``plan`` for the same generator object
        (`malcolm.scan.planned`) and know this operation as their caller's
        (validated.py)."""
        # a plan was made: malcolm.scan is loaded (never at start-up)
        from malcolm.scan.planned import PLANNED, set_planned

        planned = set_planned(params.get("generator"), plan.points)
        caller = CALLER.set(object())
        try:
            return await self.operation(name, coro)
        finally:
            CALLER.reset(caller)
            PLANNED.reset(planned)

    async def _plan(self, params: Mapping[str, Any]) -> ScanPlan:
        """The scan ``params`` describe, planned off the loop (BadValueError
        naming what is wrong)."""
        return await plan_scan_off_loop(self.mri, params, self.simultaneous_axes.value)

    @staticmethod
    def _tweaked(tweaked: Mapping[str, Any], given: Mapping[str, Any]) -> bool:
        """Whether Validate changed a parameter (compared by identity: a
        tweak is a new value; arrays have no ==)."""
        return tweaked.keys() != given.keys() or any(
            tweaked[k] is not v for k, v in given.items()
        )

    def _device_for(self, params: Mapping[str, Any], plan: ScanPlan) -> Device:
        """A device for hooks checking ``params``, whose scan is ``plan``."""
        device = Device(self)
        device.params = dict(params)
        device.points = plan.points
        return device

    async def do_configure(self, **params: Any) -> None:
        """Validate the parameters and set up the scan; ends Armed.

        The scan's points are computed in a worker thread (the loop stays
        live) before anything moves: a scan that cannot be done is refused
        and changes nothing."""
        first = await self._plan(params)  # BadValueError: nothing changed
        device = self._device_for(params, first)
        validated, self._validated = self._validated, None
        if validated is not None and validated.holds_for(CALLER.get(), params):
            self._prevalidated = (device, validated.results)

        async def adopt() -> None:
            # the parameters as the parts validated them; still resting
            plan = first
            if self._tweaked(device.params, params):
                plan = await self._plan(device.params)
                device.points = plan.points
            self.plan = plan

        async def configure() -> None:
            before = self.device
            self.device = device
            try:
                await self.fire("configure", before_move=adopt)
            except BaseException:
                if self.device is device and not self.is_busy():
                    self.device = before  # refused: nothing changed
                raise
            await self.settle()

        await self._planned_operation("configure", configure(), params, first)

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

    async def do_abort(self) -> None:
        """Stop whatever is running; a pending run() fails. Ends Aborted."""

        async def abort() -> None:
            self.stop_tasks()
            self._paused = False
            await self.fire("abort")
            await self.settle()

        await self.operation("abort", abort(), interrupt=True)


def overall_progress(steps: Mapping[str, int]) -> int:
    """The scan's progress from the steps each part still working reported:
    the slowest part's."""
    return min(steps.values())

"""Controller: a thin interpreter of a state-machine model for one block.

The model (``models/*.yaml``) says which states exist, which triggers move
between them, which phases each move runs and which calls and puts are
allowed where. The controller only: checks a call against the model, runs
the phases of the chosen transition (each phase runs every part function
registered for it, concurrently), fires the trigger on the ``transitions``
machine, and leaves busy states by firing ``done``. Anything that raises
sends the block to Fault with the message in ``health``.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable, Mapping, Sequence
from typing import Any, ClassVar

from malcolm.core import (
    AbortedError,
    Alarm,
    Attribute,
    BadValueError,
    Block,
    ChoiceMeta,
    MalcolmError,
    Method,
    MethodMeta,
    NotAllowedError,
    NotWriteableError,
    Process,
    StringMeta,
)
from malcolm.fsm import Model, Transition, load_model
from malcolm.hooks import Hook, Task, run_phase
from malcolm.hooks.signature import timeout_problem
from malcolm.parts.base import Part, PartRegistrar

log = logging.getLogger(__name__)

DEFAULT_PHASE_TIMEOUT = 60.0


class _Guards:
    """The object the transitions machine runs on: guards resolve to the controller."""

    def __init__(self, controller: Controller) -> None:
        self._controller = controller
        #: guard answers to replay during a move (see Controller.move)
        self.cached: dict[str, bool] | None = None

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_"):
            raise AttributeError(name)
        cached = self.__dict__.get("cached")
        if cached is not None and name in cached:
            value = cached[name]
            return lambda: value
        return getattr(self._controller, name)


class Device:
    """What hook functions receive: the block's live scan state and parameters."""

    def __init__(self, controller: Controller) -> None:
        self.controller = controller
        self.mri = controller.mri
        self.params: dict[str, Any] = {}
        self.part_info: dict[str, dict[str, Any]] = {}

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_"):
            raise AttributeError(name)
        params = self.__dict__.get("params", {})
        if name in params:
            return params[name]
        block = self.controller.block
        if name in block and isinstance(block[name], Attribute):
            return block[name].value
        raise AttributeError(f"{self.mri}: the device has no {name!r}")


class Controller:
    """Interprets the ``stateful`` model; subclasses pick richer models."""

    model_name: ClassVar[str] = "stateful"

    def __init__(
        self,
        mri: str,
        parts: Sequence[Part] = (),
        description: str = "",
        phase_timeout: float | None = DEFAULT_PHASE_TIMEOUT,
        phase_timeouts: Mapping[str, float] | None = None,
        model: Model | str | None = None,
    ) -> None:
        self.mri = mri
        problems = [timeout_problem("phase_timeout", phase_timeout)]
        for phase, seconds in dict(phase_timeouts or {}).items():
            problems.append(timeout_problem(f"phase_timeouts.{phase}", seconds, False))
        problems = [p for p in problems if p]
        if problems:
            raise ValueError(f"{mri}: " + "; ".join(problems))
        if isinstance(model, Model):
            self.model = model
        else:
            self.model = load_model(model or self.model_name)
        self.block = Block(mri, description)
        self.process: Process | None = None
        self.phase_timeout = phase_timeout
        self.phase_timeouts = dict(phase_timeouts or {})
        self.parts: dict[str, Part] = {}
        self.hooks: dict[str, list[Hook]] = {}
        self.tasks: dict[str, Task] = {}
        self._registrars: dict[str, PartRegistrar] = {}
        #: parts whose hooks do not run (e.g. children hidden in the palette)
        self.inactive: set[str] = set()
        self.device = Device(self)
        self._fsm = _Guards(self)
        self._machine = self.model.build_machine(self._fsm)
        self._op: asyncio.Task[Any] | None = None
        self._claim: object | None = None  # an interrupter waiting to take over
        self._claim_name = ""
        self._guard_values: dict[str, bool] = {}
        self._op_name = ""
        self.state_listeners: list[Callable[[str, str], None]] = []
        #: problems parts report (a lost connection...), shown in health
        self._part_problems: dict[str, str] = {}
        self._fault_message: str | None = None
        self.health = self._add_attr("health", StringMeta("Why the block is in Fault"))
        self.health.set_value("OK")
        self.state = self._add_attr(
            "state", ChoiceMeta(list(self.model.states), "State of the block")
        )
        self.state.set_value(self.model.initial)
        self.setup_fields()
        for name in self.model.methods:
            self.add_call(name)
        for part in parts:
            self.add_part(part)
        self._update_writeable()

    # ---- building the block
    def _add_attr(self, name: str, meta: Any) -> Attribute:
        attr = Attribute(name, meta)
        self.block.add(attr)
        return attr

    def setup_fields(self) -> None:
        """Subclasses add their own attributes here."""

    def method_meta(self, name: str) -> MethodMeta:
        """The meta of a model call: ``method_meta_<name>()`` if defined."""
        maker = getattr(self, f"method_meta_{name}", None)
        if maker is not None:
            return maker()
        impl = getattr(self, f"do_{name}", None)
        doc = (impl.__doc__ or "").strip().splitlines() if impl else []
        return MethodMeta(description=doc[0] if doc else name)

    def add_call(self, name: str) -> None:
        """Expose a model call as a method if the controller implements it."""
        impl = getattr(self, f"do_{name}", None)
        if impl is not None and name not in self.block:
            self.block.add(Method(name, self.method_meta(name), impl))

    def add_part(self, part: Part) -> None:
        if part.name in self.parts:
            raise ValueError(f"{self.mri}: two parts are called {part.name!r}")
        self.parts[part.name] = part
        registrar = PartRegistrar(self, part)
        self._registrars[part.name] = registrar
        part.setup(registrar)
        for phase, func in part.hook_functions():
            if phase not in self.model.phases:
                raise ValueError(
                    f"{self.mri}: part {part.name!r} hooks {func.__name__} into"
                    f" phase {phase!r}, which model {self.model.name} does not have"
                )
            try:
                hook = Hook.make(part.name, phase, func)
            except TypeError as e:
                raise ValueError(f"{self.mri}: {e}") from None
            self.hooks.setdefault(phase, []).append(hook)
        if self.process is not None:
            self.tasks[part.name] = Task(self.process, part.name, self._on_progress)

    def remove_part(self, name: str) -> None:
        """Take a part out: its hooks, the fields and arguments it added, its task."""
        self.parts.pop(name)
        registrar = self._registrars.pop(name)
        for phase in list(self.hooks):
            self.hooks[phase] = [h for h in self.hooks[phase] if h.part != name]
        for field in registrar.fields:
            self.block.remove(field)
        for arg in registrar.configure_args:
            self.remove_configure_arg(arg)
        task = self.tasks.pop(name, None)
        if task is not None:
            task.stop()

    def add_configure_arg(
        self, name: str, meta: Any, default: Any, required: bool
    ) -> None:
        raise ValueError(f"{self.mri}: only runnable blocks take configure arguments")

    def remove_configure_arg(self, name: str) -> None:
        """Undo add_configure_arg (runnable blocks)."""

    def _on_progress(self, part: str, steps: int) -> None:
        """Runnable controllers track progress; others ignore it."""

    # ---- lifecycle
    async def start(self) -> None:
        """Create the parts' tasks and run Disabled -> Resetting -> Ready."""
        assert self.process is not None
        for name in self.parts:
            self.tasks.setdefault(name, Task(self.process, name, self._on_progress))
        try:
            await self.operation("init", self._transition_and_settle("init"))
        except Exception as e:
            # one block that cannot start must not stop the others: it waits
            # (Fault or Disabled, the reason in health) for a reset
            log.error("%s did not start: %s", self.mri, _describe(e))

    async def stop(self) -> None:
        self.cancel_now()
        for task in self.tasks.values():
            task.stop()

    # ---- the interpreter
    @property
    def current(self) -> str:
        return str(self._fsm.state)

    def choose(self, trigger: str) -> Transition:
        """The first transition for ``trigger`` from here whose guards pass."""
        state = self.current
        values: dict[str, bool] = {}

        def guard(name: str) -> bool:
            if name not in values:
                values[name] = bool(getattr(self, name)())
            return values[name]

        for t in self.model.transitions_for(trigger, state):
            if all(guard(g) for g in t.guards) and not any(guard(g) for g in t.unless):
                # every guard an earlier candidate asked, as it answered then
                self._guard_values = values
                return t
        raise NotAllowedError(f"{self.mri}: cannot {trigger} in state {state}")

    async def fire(self, trigger: str) -> Transition:
        """Run the phases of the chosen transition, then move along it.

        The guards are evaluated once, when the transition is chosen: the
        move goes to that transition's destination even if the phases changed
        what the guards look at.
        """
        t = self.choose(trigger)
        for phase in t.phases:
            await self.run_phase(phase)
        self.move(trigger, t.dest)
        return t

    def move(self, trigger: str, dest: str | None = None) -> None:
        """Fire ``trigger`` on the machine; with ``dest``, the guards answer as
        they did when ``choose`` picked the transition to ``dest``."""
        before = self.current
        self._fsm.cached = self._guard_values if dest is not None else None
        try:
            self._fsm.trigger(trigger)
        finally:
            self._fsm.cached = None
        after = self.current
        if dest is not None and after != dest:
            raise RuntimeError(
                f"{self.mri}: {trigger} from {before} went to {after}, not {dest}"
            )
        self.state.set_value(after)
        self._update_writeable()
        for listener in list(self.state_listeners):
            listener(before, after)

    async def settle(self) -> None:
        """Leave busy states by firing ``done`` until the block rests."""
        while self.model.states[self.current].busy:
            await self.fire("done")

    async def _transition_and_settle(self, trigger: str) -> None:
        await self.fire(trigger)
        await self.settle()

    async def run_phase(
        self, phase: str, device: Device | None = None
    ) -> dict[str, Any]:
        """Run ``phase``; hooks get ``device`` (by default the block's own)."""
        device = device or self.device
        await self.before_phase(phase)
        timeout = self.phase_timeouts.get(phase, self.phase_timeout)
        results = await run_phase(
            phase,
            [h for h in self.hooks.get(phase, ()) if h.part not in self.inactive],
            self.tasks,
            device,
            timeout,
        )
        device.part_info[phase] = results
        await self.after_phase(phase, results)
        return results

    async def before_phase(self, phase: str) -> None:
        """Controller logic that must happen before the parts run ``phase``."""

    async def after_phase(self, phase: str, results: dict[str, Any]) -> None:
        """Controller logic that uses what the parts returned from ``phase``."""

    def _update_writeable(self) -> None:
        state = self.current
        for name, fld in self.block.methods.items():
            if name in self.model.methods:
                fld.set_writeable(self.model.allows(name, state))
        for name, rule in self.model.attributes.items():
            if name in self.block:
                attr = self.block[name]
                if isinstance(attr, Attribute):
                    attr.set_writeable(state in rule.allowed)

    # ---- operations
    def check_allowed(self, call: str) -> None:
        state = self.current
        if call in self.model.methods and not self.model.allows(call, state):
            allowed = ", ".join(sorted(self.model.methods[call])) or "no state"
            raise NotAllowedError(
                f"{self.mri}: {call}() is not allowed in state {state}"
                f" (allowed in {allowed})"
            )

    def side_operations(self) -> list[asyncio.Future[Any]]:
        """Work running beside the main operation (a runnable's seek)."""
        return []

    def busy_with(self) -> str | None:
        """What is in progress (so another operation must wait), or None."""
        if self._claim is not None:
            return self._claim_name
        if self._op is not None and not self._op.done():
            return self._op_name
        if any(not f.done() for f in self.side_operations()):
            return "a pause or seek"
        return None

    async def operation(self, name: str, coro: Any, interrupt: bool = False) -> Any:
        """Run one operation at a time; Fault on error, AbortedError if cancelled.

        ``interrupt`` operations (abort, disable) cancel whatever is in
        progress first; of two racing interrupters the later one wins and the
        earlier gets AbortedError. Others are refused while anything runs.
        """
        busy = self.busy_with()
        if busy is not None and not interrupt:
            coro.close()
            raise NotAllowedError(
                f"{self.mri}: cannot {name} while {busy} is in progress"
                f" (state {self.current})"
            )
        if interrupt:
            claim = object()
            self._claim, self._claim_name = claim, name
            try:
                await self.cancel_operation()
            finally:
                superseded = self._claim is not claim
                if not superseded:
                    self._claim = None
            if superseded:
                coro.close()
                raise AbortedError(
                    f"{self.mri}: {name} was superseded by {self._claim_name}"
                )
        op = asyncio.ensure_future(self._guarded(name, coro))
        self._op, self._op_name = op, name
        await asyncio.wait({op})
        if op.cancelled():
            raise AbortedError(f"{self.mri}: {name} was aborted")
        return op.result()

    async def cancel_operation(self) -> None:
        """Cancel the main operation and any side work, and wait for them."""
        running = [f for f in [self._op, *self.side_operations()] if f is not None]
        running = [f for f in running if not f.done()]
        for f in running:
            f.cancel()
        if running:
            await asyncio.wait(running)

    def cancel_now(self) -> None:
        """Cancel everything in progress without waiting (fault, stop)."""
        me = asyncio.current_task()
        for f in [self._op, *self.side_operations()]:
            if f is not None and not f.done() and f is not me:
                f.cancel()

    async def _guarded(self, name: str, coro: Any) -> Any:
        try:
            return await coro
        except asyncio.CancelledError:
            raise
        except (NotAllowedError, BadValueError) as e:
            # refused before anything moved: nothing changed; but if the block
            # had already left a resting state it must not stay busy for ever
            if self.model.states[self.current].busy:
                await self.go_fault(f"{name} stopped half way: {e}")
            raise
        except Exception as e:
            await self.go_fault(e)
            raise

    async def go_fault(self, error: BaseException | str) -> None:
        message = error if isinstance(error, str) else _describe(error)
        log.warning("%s: fault: %s", self.mri, message)
        for task in self.tasks.values():
            task.stop()
        self._fault_message = message
        self.health.set_value(message, alarm=Alarm.major(message))
        if self.model.transitions_for("fault", self.current):
            self.move("fault")

    def set_health_ok(self) -> None:
        """Forget the fault's reason; health shows the parts' problems, or OK."""
        self._fault_message = None
        self._show_health()

    def set_part_health(self, part: str, message: str | None) -> None:
        """A part reports a problem (``message``) or that it is over (None).

        ``health`` shows a fault's reason first, then the parts' problems
        (``part: message``, joined by ``; ``), else ``OK``. Reporting a
        problem does not change the state: the part decides whether it is a
        fault.
        """
        if message is None:
            self._part_problems.pop(part, None)
        else:
            self._part_problems[part] = str(message)
        self._show_health()

    def _show_health(self) -> None:
        if self._fault_message is not None:
            return  # a fault's reason stays until reset
        if self._part_problems:
            text = "; ".join(f"{p}: {m}" for p, m in self._part_problems.items())
            if text != self.health.value:
                self.health.set_value(text, alarm=Alarm.minor(text))
        elif self.health.value != "OK" or self.health.alarm != Alarm.ok:
            self.health.set_value("OK", alarm=Alarm.ok)

    # ---- calls and puts (what every transport uses)
    async def call(self, name: str, params: Mapping[str, Any] | None = None) -> Any:
        method = self.block.method(name)
        args = method.meta.validate_args(f"{self.mri}.{name}", params or {})
        self.check_allowed(name)
        method.set_took(args)
        try:
            result = method.handler(**args) if method.handler else None
            if asyncio.iscoroutine(result):
                result = await result
        except Exception as e:
            method.set_returned({}, Alarm.major(_describe(e)))
            raise
        returned = result if isinstance(result, Mapping) else {}
        method.set_returned(returned, Alarm.ok)
        return result

    async def put(self, name: str, value: Any) -> None:
        attr = self.block.attribute(name)
        state = self.current
        rule = self.model.attributes.get(name)
        if rule is not None and state not in rule.allowed:
            allowed = ", ".join(sorted(rule.allowed)) or "no state"
            raise NotAllowedError(
                f"{self.mri}.{name}: cannot put in state {state} (allowed in {allowed})"
            )
        if rule is None and not attr.meta.writeable:
            raise NotWriteableError(f"{self.mri}.{name} is read-only")
        value = attr.validate(value)
        handler = getattr(self, f"put_{name}", None) or attr.put_handler
        if handler is None:
            attr.set_value(value, validate=False)
            return
        result = handler(value)
        if asyncio.iscoroutine(result):
            await result

    # ---- the stateful calls
    async def do_reset(self) -> None:
        """Leave Fault, Disabled, Aborted, Armed or Finished for Ready."""

        async def reset() -> None:
            for task in self.tasks.values():
                task.stop()
            self.set_health_ok()
            await self._transition_and_settle("reset")

        await self.operation("reset", reset())

    async def do_disable(self) -> None:
        """Stop whatever is running and go to Disabled."""

        async def disable() -> None:
            for task in self.tasks.values():
                task.stop()
            await self._transition_and_settle("disable")

        await self.operation("disable", disable(), interrupt=True)


def _describe(error: BaseException) -> str:
    if isinstance(error, MalcolmError):
        return str(error)
    return f"{type(error).__name__}: {error}"

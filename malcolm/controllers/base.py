"""Controller: a thin interpreter of a state-machine model for one block.

The model (``models/*.yaml``) says which states exist, which triggers move
between them, which phases each move runs and which calls and puts are
allowed where. The controller only: checks a call against the model, runs
the phases of the chosen transition (each phase runs every part function
registered for it, concurrently), moves, and leaves busy states by firing
``done``. Its jobs live in mixins, one module each:

- :mod:`.interpreter`: choose a transition, run its phases, move;
- :mod:`.operations`: one operation at a time; refusal or Fault on failure;
- :mod:`.health`: ``health`` and the move to Fault;
- :mod:`.writers`: who is writing a field (the origin of puts in flight).
"""

from __future__ import annotations

import asyncio
import functools
import logging
from collections.abc import Callable, Coroutine, Generator, Mapping, Sequence
from threading import get_ident
from time import time_ns
from types import CoroutineType, coroutine
from typing import Any, ClassVar

from malcolm.core import (
    Alarm,
    Attribute,
    BadValueError,
    Block,
    ChoiceMeta,
    Method,
    MethodLog,
    MethodMeta,
    NotAllowedError,
    NotWriteableError,
    Process,
    StringMeta,
    TimeStamp,
)
from malcolm.core.callplan import plan_args
from malcolm.fsm import Model, load_model
from malcolm.hooks import Hook, Task
from malcolm.hooks.signature import timeout_problem
from malcolm.parts.base import Part, PartRegistrar

from .device import Device
from .health import Health, describe
from .interpreter import Interpreter
from .operations import Operations
from .writers import PutsInFlight

__all__ = ["DEFAULT_PHASE_TIMEOUT", "Controller", "Device"]

log = logging.getLogger(__name__)

#: seconds a phase may take unless the model tags it ``long`` or the
#: controller's ``phase_timeouts`` names it
DEFAULT_PHASE_TIMEOUT = 60.0

_new = object.__new__
_OK = Alarm.ok
#: what a MethodLog publishes as it is (fields._new_log's test)
_PLAIN = frozenset({float, int, str, bool, type(None)})


def _ok_log(value: dict[str, Any]) -> MethodLog:
    """A MethodLog of ``value`` (all present), no alarm, stamped now: what
    ``Method.set_took``/``set_returned`` make, built without their checks
    (``Controller.call``'s took and returned on the loop)."""
    seconds, nanoseconds = divmod(time_ns(), 1_000_000_000)
    stamp = _new(TimeStamp)  # TimeStamp.now(), in line
    stamp.__dict__.update(secondsPastEpoch=seconds, nanoseconds=nanoseconds, userTag=0)
    log = _new(MethodLog)
    log.__dict__ = {
        "value": value,
        "present": list(value),
        "alarm": _OK,
        "timeStamp": stamp,
    }
    return log


#: not yet looked up (None is a lookup's answer: no such method)
_UNKNOWN: Any = object()


@functools.cache
def builtin_phase_roles() -> dict[str, str]:
    """Phase name -> role, over the builtin models (``models/``)."""
    roles: dict[str, str] = {}
    for name in ("runnable_device", "area_detector_runnable_device"):
        for phase, info in load_model(name).phase_info.items():
            if info.role is not None:
                roles.setdefault(phase, info.role)
    return roles


@coroutine
def _rest(coro: Coroutine[Any, Any, Any], first: Any) -> Generator[Any, Any, Any]:
    """Await ``coro`` from its second step on, ``first`` being what its
    first step (taken by :meth:`Controller.call`) yielded: each send and
    throw of the awaiting Task goes on to ``coro``; its return is this."""
    yielded = first
    while True:
        try:
            sent = yield yielded
        except GeneratorExit:
            coro.close()
            raise
        except BaseException as e:  # thrown in: a cancellation, mostly
            try:
                yielded = coro.throw(e)
            except StopIteration as done:
                return done.value
        else:
            try:
                yielded = coro.send(sent)
            except StopIteration as done:
                return done.value


class Controller(Interpreter, Operations, Health):
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
        self.state_listeners: list[Callable[[str, str], None]] = []
        self.puts_in_flight = PutsInFlight()
        #: attribute name -> this controller's ``put_<name>`` (None: it has none)
        self._put_methods: dict[str, Callable[[Any], Any] | None] = {}
        self._state = self.model.initial
        self._init_operations()
        self._init_health()
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
            method = Method(name, self.method_meta(name), impl)
            method.meta.writeable = self.model.allows(name, self._state)
            self.block.add(method)

    def add_part(self, part: Part) -> None:
        """Add a part: its fields (``setup``) and its hook functions."""
        if part.name in self.parts:
            raise ValueError(f"{self.mri}: two parts are called {part.name!r}")
        self.parts[part.name] = part
        registrar = PartRegistrar(self, part)
        self._registrars[part.name] = registrar
        part.setup(registrar)
        for declared, func in part.hook_functions():
            phase = self.resolve_phase(declared)
            if phase is None:
                raise ValueError(
                    f"{self.mri}: part {part.name!r} hooks {func.__name__} into"
                    f" phase {declared!r}, which model {self.model.name} does not"
                    " have (by name or by role)"
                )
            try:
                hook = Hook.make(part.name, phase, func)
            except TypeError as e:
                raise ValueError(f"{self.mri}: {e}") from None
            self.hooks.setdefault(phase, []).append(hook)
        if self.process is not None:
            self.tasks[part.name] = self.make_task(part.name)

    def resolve_phase(self, declared: str) -> str | None:
        """The model's phase for a part's ``@Model.Phase`` decorator: the
        phase of that name, else the phase with the role the builtin models
        give that name (so parts work on a model that renames its phases)."""
        if declared in self.model.phases:
            return declared
        role = builtin_phase_roles().get(declared)
        return self.model.phase_for(role) if role is not None else None

    def make_task(self, part: str) -> Task:
        """The Task a part's hooks get: its puts carry this block's mri."""
        assert self.process is not None
        return Task(self.process, part, self._on_progress, origin=self.mri)

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

    def stop_tasks(self) -> None:
        """Cancel what the parts' tasks started and drop their subscriptions."""
        for task in self.tasks.values():
            task.stop()

    # ---- lifecycle
    async def start(self) -> None:
        """Create the parts' tasks and run Disabled -> Resetting -> Ready."""
        assert self.process is not None
        for name in self.parts:
            if name not in self.tasks:
                self.tasks[name] = self.make_task(name)
        try:
            await self.operation("init", self._transition_and_settle("init"))
        except Exception as e:
            # one block that cannot start must not stop the others: it waits
            # (Fault, or Disabled if Init refused, the reason in health) for
            # a reset
            message = describe(e)
            log.error("%s did not start: %s", self.mri, message)
            if self._fault_message is None:
                self._fault_message = message
                self.health.set_value(message, alarm=Alarm.major(message))

    async def stop(self) -> None:
        self.cancel_now()
        self.stop_tasks()

    # ---- calls and puts (what every transport uses)
    def check_allowed(self, call: str) -> None:
        """NotAllowedError naming the state if the model forbids ``call`` now."""
        state = self._state
        if call in self.model.methods and not self.model.allows(call, state):
            allowed = ", ".join(sorted(self.model.methods[call])) or "no state"
            raise NotAllowedError(
                f"{self.mri}: {call}() is not allowed in state {state}"
                f" (allowed in {allowed})"
            )

    async def call(self, name: str, params: Mapping[str, Any] | None = None) -> Any:
        """Call method ``name``: arguments checked, then the model's rule.

        The method's call plan (:mod:`malcolm.core.callplan`) checks the
        arguments; on the loop, the took and returned are made here, in line
        (what ``Method.set_took``/``set_returned`` do), the took held back
        (:meth:`Process.hold`) to go with the returned as one batch
        (:meth:`Process.complete`) if the method does not wait and publishes
        nothing meanwhile."""
        method = self.block.method(name)
        plan = method.args_plan
        if plan is None or (args := plan(method.meta, params)) is None:
            plan = method.args_plan = plan_args(method.meta, f"{self.mri}.{name}")
            args = plan(method.meta, params)
        allowed = self.model.methods.get(name)  # check_allowed's test, in line
        if allowed is not None and self._state not in allowed:
            self.check_allowed(name)  # raises, naming the state
        process = self.process
        owner = self.block.owner
        # on the loop (the common case): the logs made here, in line; else
        # by Method.set_took/set_returned (their loop guard refuses)
        fast = process is not None and owner is not None and owner.thread == get_ident()
        if fast:
            # the took (set_took's work): the arguments are the plan's own dict
            took = method.took = _ok_log(args)
            held = process.hold(  # type: ignore[union-attr]
                self.mri,
                [[name, "took"], took if plan.scalars else took.to_dict()],
                [name, "returned"],
            )
        else:
            method.set_took(args, process.hold if process is not None else None)
        handler = method.handler
        try:
            result = handler(**args) if handler else None
            # an async def's coroutine, or nothing, told apart without a call
            if type(result) is CoroutineType or (
                result is not None and asyncio.iscoroutine(result)
            ):
                try:  # its first step now: one that does not wait ends here
                    step = result.send(None)
                except StopIteration as done:
                    result = done.value
                else:  # it waits: its took is published first
                    if process is not None:
                        process.release()
                    result = await _rest(result, step)
        except Exception as e:
            method.set_returned({}, Alarm.major(describe(e)))
            raise
        except BaseException:
            if process is not None:
                process.release()
            raise
        is_map = type(result) is dict or isinstance(result, Mapping)
        if not fast:
            method.set_returned(result if is_map else {}, Alarm.ok)
            return result
        # the returned (set_returned's work), with the took if still held
        value = dict(result) if is_map and result else {}
        returned = method.returned = _ok_log(value)
        if not _PLAIN.issuperset(map(type, value.values())):
            returned = returned.to_dict()  # (what the method keeps may change)
        change = [[name, "returned"], returned]
        if not process.complete(held, change):  # type: ignore[union-attr]
            self.block.notify([change])  # (it waited or published; not hosted: -)
        return result

    async def put(self, name: str, value: Any) -> None:
        """Put ``value`` to attribute ``name``: the model's rule, the meta's
        check, then its handler (``put_<name>`` or the part's)."""
        attr = self.block.attribute(name)
        state = self._state
        rule = self.model.attributes.get(name)
        if rule is not None and state not in rule.allowed:
            allowed = ", ".join(sorted(rule.allowed)) or "no state"
            raise NotAllowedError(
                f"{self.mri}.{name}: cannot put in state {state} (allowed in {allowed})"
            )
        if rule is None and not attr.meta.writeable:
            raise NotWriteableError(f"{self.mri}.{name} is read-only")
        try:  # attr.validate, in line
            value = attr.meta.validate(value)
        except BadValueError as e:
            raise BadValueError(f"{self.mri}.{name}: {e}") from None
        own = self._put_methods.get(name, _UNKNOWN)
        if own is _UNKNOWN:  # looked up once per attribute, not per put
            own = self._put_methods[name] = getattr(self, f"put_{name}", None)
        handler = own or attr.put_handler
        # begin/end rather than the context manager: once per put
        puts_in_flight = self.puts_in_flight
        entry = puts_in_flight.begin(name)
        try:
            if handler is None:
                attr.set_value(value, validate=False)
                return
            result = handler(value)
            if asyncio.iscoroutine(result):
                await result
        finally:
            puts_in_flight.end(name, entry)

    def writer_of(self, field: str) -> str | None:
        """The origin (an mri) of the latest put to ``field`` in flight."""
        return self.puts_in_flight.writer_of(field)

    # ---- the stateful calls
    async def do_reset(self) -> None:
        """Leave Fault, Disabled, Aborted, Armed or Finished for Ready."""

        async def reset() -> None:
            self.stop_tasks()
            self.set_health_ok()
            await self._transition_and_settle("reset")

        await self.operation("reset", reset())

    async def do_disable(self) -> None:
        """Stop whatever is running and go to Disabled."""

        async def disable() -> None:
            self.stop_tasks()
            await self._transition_and_settle("disable")

        await self.operation("disable", disable(), interrupt=True)

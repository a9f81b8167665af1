"""Hypothesis state machines that drive LIVE controllers, one per model.

Each machine hosts a controller in a :class:`Process` on its own asyncio loop
(kept for the whole example; every rule runs ``loop.run_until_complete``).
A probe part hooks every phase of the model: it records which phase ran in
which state, and the rules make it fail, hang or dawdle in a chosen phase.

Rules call everything the model knows in ANY state, one at a time or two at
once (the first stalls in a chosen phase while the second is issued).
Checked throughout:

* the states the block passes through (a ``delta=False`` subscription to
  ``state.value``) form a path of ``model.moves()``, and when a move has
  phases they are the last phases run while the block was in the source state;
* a call or put the model does not allow raises NotAllowedError naming the
  state and changes nothing;
* after every rule the block rests (no busy state), health is OK outside Fault
  and Disabled, and a runnable has ``completed <= configured <= total``;
* an injected part failure or phase timeout ends in Fault with the part and
  the phase named in ``health``; reset from Fault returns to Ready;
* abort and disable make a pending ``run()`` fail with AbortedError;
* configure, run, pause, seek and resume move the steps as interop.md §1 says.
"""

from __future__ import annotations

import asyncio
import functools
import math
import shutil
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

from hypothesis import HealthCheck, event, settings
from hypothesis import strategies as st
from hypothesis.stateful import (
    RuleBasedStateMachine,
    initialize,
    invariant,
    precondition,
    rule,
)

from malcolm.controllers.base import Controller
from malcolm.controllers.manager import ManagerController
from malcolm.controllers.runnable import RunnableController
from malcolm.controllers.stateful import StatefulController
from malcolm.core import (
    AbortedError,
    BadValueError,
    NotAllowedError,
    PhaseTimeoutError,
    Process,
)
from malcolm.fsm import Model, load_model, model_class
from malcolm.parts.base import Part, PartRegistrar
from malcolm.parts.demo import SimDetectorPart

MRI = "BLOCK"
PROBE = "probe"
PHASE_TIMEOUT = 0.2  # a hung phase faults after this long
HANG = 30.0  # longer than any timeout: only the phase timeout ends it
SLOW = 0.01  # how long a slowed phase stalls before going on
STEP_TIME = 0.001  # seconds per scan point
CALL_TIMEOUT = 5.0  # a call taking longer than this is a hang (test failure)


def _settings(examples: int) -> settings:
    return settings(
        max_examples=examples,
        stateful_step_count=40,
        deadline=None,
        suppress_health_check=[HealthCheck.too_slow],
    )


# --------------------------------------------------------------------------
# The probe part


class ProbePart(Part):
    """Hooks every phase of a model; the machine scripts what each does."""

    def __init__(self, name: str, stepping_phase: str | None) -> None:
        super().__init__(name)
        self.stepping_phase = stepping_phase
        self.controller: Controller | None = None
        self.where: Callable[[], int] = lambda: 0
        self.fail_next: set[str] = set()
        self.hang_next: set[str] = set()
        self.slow_next: dict[str, float] = {}
        self.slow_entered: asyncio.Event | None = None
        # (phase, "fail" | "hang") for every scripted misbehaviour that happened
        self.fired: list[tuple[str, str]] = []
        # (phase, controller state, index of that state in the machine's log)
        # for phases a move runs (not validate(), which has a device of its own)
        self.calls: list[tuple[str, str, int]] = []
        self.queries: list[tuple[str, str]] = []  # (phase, state) for validate()

    def setup(self, registrar: PartRegistrar) -> None:
        self.controller = registrar.controller

    async def behave(self, phase: str, task: Any, device: Any) -> None:
        assert self.controller is not None
        if device is self.controller.device:
            self.calls.append((phase, self.controller.current, self.where()))
        else:
            self.queries.append((phase, self.controller.current))
        if phase in self.fail_next:
            self.fail_next.discard(phase)
            self.fired.append((phase, "fail"))
            raise RuntimeError(f"injected failure in {phase}")
        if phase in self.hang_next:
            self.hang_next.discard(phase)
            self.fired.append((phase, "hang"))
            await asyncio.sleep(HANG)
        if phase in self.slow_next:
            delay = self.slow_next.pop(phase)
            if self.slow_entered is not None:
                self.slow_entered.set()
            await asyncio.sleep(delay)
        if phase == self.stepping_phase:
            for step in range(device.completedSteps, device.configuredSteps):
                await asyncio.sleep(STEP_TIME)
                task.report_progress(step + 1)


def _hook(phase: str) -> Callable[..., Any]:
    async def hook(self: ProbePart, task: Any, device: Any) -> None:
        await self.behave(phase, task, device)

    hook.__name__ = f"on_{phase}"
    return hook


def probe_class(model: Model) -> type[ProbePart]:
    """A ProbePart subclass with a hook for every phase of ``model``."""
    phases = model_class(model)
    namespace = {
        f"on_{name}": getattr(phases, name)(_hook(name)) for name in model.phases
    }
    return type(f"Probe{model.name}", (ProbePart,), namespace)


# --------------------------------------------------------------------------
# Scans


def _line(axis: str, size: int) -> dict[str, Any]:
    return {
        "typeid": "scanpointgenerator:generator/LineGenerator:1.0",
        "axes": [axis],
        "units": ["mm"],
        "start": [0.0],
        "stop": [1.0],
        "size": size,
        "alternate": False,
    }


@dataclass(frozen=True)
class Scan:
    params: dict[str, Any]
    valid: bool
    total: int
    boundaries: tuple[int, ...]  # where runs end: multiples of a run, breakpoints

    def next_end(self, completed: int) -> int:
        """Where a run starting at ``completed`` ends (total once done)."""
        return min([b for b in self.boundaries if b > completed] or [self.total])

    def __repr__(self) -> str:  # short, for hypothesis' step printout
        return f"Scan({self.params!r}, valid={self.valid})"


@st.composite
def scans(draw: st.DrawFn, valid_only: bool = False) -> Scan:
    """1 to 6 points in one or two dimensions (y outside x), random
    axesToMove (omitted, valid or not) and breakpoints (none, valid or not)."""
    if draw(st.booleans()):
        sizes = [draw(st.integers(1, 6))]
    else:
        outer = draw(st.integers(1, 3))
        sizes = [outer, draw(st.integers(1, 6 // outer))]
    axes = ["y", "x"][-len(sizes) :]
    total = math.prod(sizes)
    params: dict[str, Any] = {
        "generator": {
            "typeid": "scanpointgenerator:generator/CompoundGenerator:1.0",
            "generators": [_line(a, n) for a, n in zip(axes, sizes)],
            "excluders": [],
            "mutators": [],
            "duration": STEP_TIME,
        }
    }
    valid = True
    bad = [] if valid_only else ["invalid"]
    how = draw(st.sampled_from(["omit", "valid", "valid", *bad]))
    if how == "omit":
        per_run = total  # no axesToMove: the whole scan in one run
    elif how == "valid":
        inner = draw(st.integers(0, len(sizes)))  # move the inner `inner` dims
        moving = axes[len(axes) - inner :]
        params["axesToMove"] = draw(st.permutations(moving))
        per_run = math.prod(sizes[len(sizes) - inner :])
    else:
        valid = False
        per_run = total
        params["axesToMove"] = ["y"] if len(sizes) == 2 else ["z"]
    ends: list[int] = []
    how = draw(st.sampled_from(["omit", "omit", "valid", *bad]))
    if how == "valid":
        cuts = draw(st.sets(st.integers(1, total - 1))) if total > 1 else set()
        ends = sorted(cuts) + [total]
        params["breakpoints"] = [b - a for a, b in zip([0, *ends], ends)]
    elif how == "invalid":
        valid = False
        params["breakpoints"] = [total + draw(st.integers(1, 3))]
    boundaries = set(range(per_run, total + 1, per_run)) | set(ends) | {total}
    return Scan(params, valid, total, tuple(sorted(boundaries)))


# --------------------------------------------------------------------------
# Calls


@dataclass
class Outcome:
    """What a call did: the state it was made in, its result or its error."""

    name: str
    state: str
    result: Any = None
    error: BaseException | None = None

    def __repr__(self) -> str:
        what = f"raised {self.error!r}" if self.error else f"returned {self.result!r}"
        return f"{self.name}() in {self.state} {what}"


@dataclass(frozen=True)
class Call:
    name: str  # a method, or an attribute for a put
    params: Any = None  # method arguments, or the value put
    put: bool = False
    scan: Scan | None = None  # for configure and validate

    def __repr__(self) -> str:
        if self.put:
            return f"put {self.name}={self.params!r}"
        return f"{self.name}({self.params or ''})"


INTERRUPTS = {"abort": "Aborted", "disable": "Disabled"}
SESSION_CALLS = [
    *("run", "run", "run", "pause", "pause", "seek", "resume", "resume"),
    *("interrupt_a_run", "interrupt_a_run", "interrupt_a_scan_call"),
    *("validate", "misbehave", "abort", "disable", "reset"),
]


@functools.cache
def cached_model(name: str) -> Model:
    return load_model(name)


def in_state(*states: str) -> Callable[[Any], Any]:
    """A precondition: the block rests in one of ``states``."""
    return precondition(
        lambda self: self.ctrl is not None and self.ctrl.current in states
    )


# --------------------------------------------------------------------------
# The machines


class ControllerMachine(RuleBasedStateMachine):
    """Common rules: reset, disable, failures, hangs and concurrent calls."""

    model_name: ClassVar[str] = "stateful"
    runnable: ClassVar[bool] = False

    def __init__(self) -> None:
        super().__init__()
        self.model = cached_model(self.model_name)
        self.moves = self.model.moves()
        self.loop = asyncio.new_event_loop()
        self.process: Process | None = None
        self.ctrl: Controller | None = None
        self.part: ProbePart | None = None
        self.states: list[str] = []
        self.pending_run: asyncio.Task[Outcome] | None = None
        self.scan: Scan | None = None

    # ---- set up and tear down
    def make_controller(self, parts: list[Part]) -> Controller:
        return StatefulController(
            MRI, parts, phase_timeout=PHASE_TIMEOUT, model=self.model
        )

    def stepping_phase(self) -> str | None:
        return None

    @initialize(fail_init=st.integers(0, 3).map(lambda n: n == 3))
    def start(self, fail_init: bool) -> None:
        self.part = probe_class(self.model)(PROBE, self.stepping_phase())
        self.part.where = lambda: len(self.states) - 1
        self.ctrl = self.make_controller([self.part])
        assert self.ctrl.model.name == self.model.name
        self.process = Process()
        self.process.add_controller(self.ctrl)
        self.process.subscribe([MRI, "state", "value"], self.states.append, False)
        if fail_init:
            self.part.fail_next.add("Init")

        async def start() -> Outcome:
            try:
                await self.process.start()
            except Exception as e:
                return Outcome("start", "Disabled", error=e)
            return Outcome("start", "Disabled")

        out = self.run(start())
        if fail_init:
            # Init runs on Disabled -> Resetting while the block is Disabled,
            # and the model has no move Disabled -> Fault: the block stays
            # Disabled, with the failure in health; the process still starts
            # (one block that cannot start must not stop the others).
            assert out.error is None, out
            assert self.states == ["Disabled"], self.states
            self.check_health_names("Init")
        else:
            assert out.error is None, out
            assert self.states == ["Disabled", "Resetting", "Ready"], self.states

    def teardown(self) -> None:
        loop = self.loop
        try:
            if self.process is not None:
                loop.run_until_complete(asyncio.wait_for(self.process.stop(), 5))
        finally:
            tasks = asyncio.all_tasks(loop)
            for task in tasks:
                task.cancel()
            if tasks:
                loop.run_until_complete(asyncio.gather(*tasks, return_exceptions=True))
            loop.run_until_complete(loop.shutdown_asyncgens())
            loop.close()

    # ---- running things on the loop
    def run(self, coro: Any, timeout: float = CALL_TIMEOUT) -> Any:
        async def bounded() -> Any:
            try:
                return await asyncio.wait_for(coro, timeout)
            except TimeoutError:
                raise AssertionError(
                    f"hung for {timeout} s; state {self.current} (path {self.states})"
                ) from None

        return self.loop.run_until_complete(bounded())

    async def invoke(self, call: Call) -> Outcome:
        """Make a call; the state is read in the same step the call checks it."""
        assert self.process is not None
        out = Outcome(call.name, self.current)
        try:
            if call.put:
                await self.process.put([MRI, call.name], call.params)
            else:
                out.result = await self.process.post([MRI, call.name], call.params)
        except Exception as e:
            out.error = e
        return out

    @property
    def current(self) -> str:
        assert self.ctrl is not None
        return self.ctrl.current

    def allowed(self, call: Call, state: str) -> bool:
        if call.put:
            return self.model.put_allowed(call.name, state)
        return self.model.allows(call.name, state)

    def snapshot(self) -> dict[str, Any]:
        assert self.ctrl is not None
        snap = {
            "state": self.current,
            "health": self.ctrl.health.value,
            "moves": len(self.states),
        }
        if self.runnable:
            snap["steps"] = self.steps()
        return snap

    def steps(self) -> tuple[int, int, int]:
        """(completed, configured, total)."""
        c = self.ctrl
        assert isinstance(c, RunnableController)
        return (c.completed.value, c.configured.value, c.total.value)

    # ---- one call at a time
    def call(self, call: Call) -> Outcome | None:
        """Make ``call`` and check what the model says about it.

        Returns the outcome for the rule to check further, or None when
        there is nothing more to check (refused as the model says, or a
        scripted failure took over).
        """
        assert self.part is not None
        before = self.snapshot()
        fired = len(self.part.fired)
        out = self.run(self.invoke(call))
        assert out.state == before["state"]
        if not self.allowed(call, out.state):
            self.check_refused(out, before)
            self.reap_pending_run()
            return None
        event(f"{call.name} in {out.state}")
        assert not isinstance(out.error, NotAllowedError), (
            f"the model allows {call} in {out.state} but it was refused: {out}"
        )
        if call.name == "resume" and self.pending_run is not None:
            # what resume starts, the pending run() does: wait for it
            out = self.collect_pending_run()
        if len(self.part.fired) > fired:
            self.check_fault(out, self.part.fired[fired:], call)
            self.reap_pending_run()
            return None
        self.reap_pending_run()
        return out

    def check_refused(self, out: Outcome, before: dict[str, Any]) -> None:
        assert isinstance(out.error, NotAllowedError), (
            f"the model does not allow {out.name} in {out.state}: {out}"
        )
        assert out.state in str(out.error), (
            f"the message does not name the state: {out}"
        )
        self.check_unchanged(before, f"a refused {out.name}")

    def check_unchanged(self, before: dict[str, Any], what: str) -> None:
        after = self.snapshot()
        assert after == before, (
            f"{what} changed the block: {before} -> {after}"
            f" (moves {self.states[before['moves'] :]})"
        )

    def check_health_names(self, phase: str) -> None:
        assert self.ctrl is not None
        health = self.ctrl.health.value
        assert PROBE in health and phase in health, (
            f"health {health!r} does not name part {PROBE!r} and phase {phase!r}"
        )

    def check_fault(
        self, out: Outcome, fired: list[tuple[str, str]], call: Call | None
    ) -> None:
        """A scripted failure or hang happened during ``out``."""
        phase, how = fired[-1]
        if call is not None and call.name == "validate":
            # validate() is a query: a failing Validate phase is its error
            # alone; the block does not fault (see the report)
            assert out.error is not None, out
            assert self.current == out.state, (out, self.states)
            return
        ran_in = [state for p, state, _ in self.part.calls if p == phase][-1:]
        if ran_in and not self.model.states[ran_in[0]].busy:
            # a phase that runs before the block leaves a resting state can
            # only refuse: nothing moved, so nothing faults (issue 7 item 8)
            assert out.error is not None, out
            assert self.current == out.state, (out, self.states)
            return
        assert self.current == "Fault", (
            f"a part failure ({how} in {phase}) during {out} left the block"
            f" {self.current}, not Fault (path {self.states})"
        )
        assert out.error is not None, f"{out} hid a part failure ({how} in {phase})"
        if how == "hang":
            assert isinstance(out.error, PhaseTimeoutError), out
        self.check_health_names(phase)

    def expect_path(self, before: dict[str, Any], *path: str) -> None:
        got = self.states[before["moves"] :]
        assert got == list(path), f"expected the moves {list(path)}, got {got}"

    def collect_pending_run(self, timeout: float = 2.0) -> Outcome:
        """The outcome of the pending run(), which must end within ``timeout``."""
        task = self.pending_run
        assert task is not None
        self.run(asyncio.wait({task}, timeout=timeout))
        assert task.done(), (
            f"run() still pending in state {self.current} (path {self.states})"
        )
        self.pending_run = None
        return task.result()

    # ---- rules every model has
    @rule()
    def reset(self) -> None:
        before = self.snapshot()
        out = self.call(Call("reset"))
        if out is None:
            return
        assert out.error is None, out
        self.expect_path(before, "Resetting", "Ready")
        assert self.ctrl is not None and self.ctrl.health.value == "OK"

    @rule()
    def disable(self) -> None:
        before = self.snapshot()
        pending = self.pending_run
        out = self.call(Call("disable"))
        if out is None:
            return
        assert out.error is None, out
        self.expect_path(before, "Disabling", "Disabled")
        if pending is not None:
            assert pending.done(), "run() still pending"
            assert isinstance(pending.result().error, AbortedError), pending.result()

    @rule(data=st.data(), how=st.sampled_from(["fail", "fail", "hang", "behave"]))
    def misbehave(self, data: st.DataObject, how: str) -> None:
        """The probe raises (fail) or hangs until the phase timeout (hang) the
        next time it runs the chosen phase; or stops doing either (behave)."""
        assert self.part is not None
        if how == "behave":
            self.part.fail_next.clear()
            self.part.hang_next.clear()
            return
        phase = data.draw(st.sampled_from(sorted(self.model.phases)), label="phase")
        (self.part.fail_next if how == "fail" else self.part.hang_next).add(phase)

    # ---- two calls at once
    def call_names(self) -> list[str]:
        """Every call and put the block has (puts by attribute name)."""
        return ["reset", "disable"]

    def draw_call(self, data: st.DataObject, name: str, label: str) -> Call:
        return Call(name)

    def phases_of_call(self, name: str) -> list[str]:
        """The phases ``name`` may run: those of its trigger's transitions and
        of the ``done`` moves out of the busy states they lead to."""
        rule = self.model.attributes.get(name)
        trigger = rule.trigger if rule is not None else name
        if trigger == "validate":
            return ["Validate"]
        todo = [t for t in self.model.transitions if t.trigger == trigger]
        seen: set[tuple[str, str, str]] = set()
        phases: list[str] = []
        while todo:
            t = todo.pop()
            if (t.trigger, t.source, t.dest) in seen:
                continue
            seen.add((t.trigger, t.source, t.dest))
            phases += [p for p in t.phases if p not in phases]
            if self.model.states[t.dest].busy:
                todo += self.model.transitions_for("done", t.dest)
        return sorted(phases) or sorted(self.model.phases)

    def allowed_now(self) -> list[str]:
        puts = self.model.attributes
        return [
            n
            for n in self.call_names()
            if self.allowed(Call(n, put=n in puts), self.current)
        ]

    def interrupts(self) -> list[str]:
        return [n for n in ("abort", "disable", "pause") if n in self.call_names()]

    @rule(data=st.data())
    def two_calls_at_once(self, data: st.DataObject) -> None:
        """Stall the first call in a phase, make a second call meanwhile."""
        names = self.call_names()
        name = data.draw(
            st.sampled_from(self.allowed_now() or names) | st.sampled_from(names),
            label="first",
        )
        first = self.draw_call(data, name, "first")
        phase = data.draw(
            st.sampled_from(self.phases_of_call(name))
            | st.sampled_from(sorted(self.model.phases)),
            label="stall",
        )
        name = data.draw(
            st.sampled_from(self.interrupts()) | st.sampled_from(names),
            label="second",
        )
        self.two_calls(first, phase, self.draw_call(data, name, "second"))

    @rule(data=st.data())
    def interrupt_in_flight(self, data: st.DataObject) -> None:
        """A call allowed here stalls in one of its phases; abort, disable or
        pause is called meanwhile."""
        name = data.draw(
            st.sampled_from(self.allowed_now() or self.call_names()), label="first"
        )
        first = self.draw_call(data, name, "first")
        phase = data.draw(st.sampled_from(self.phases_of_call(name)), label="stall")
        name = data.draw(st.sampled_from(self.interrupts()), label="second")
        self.two_calls(first, phase, self.draw_call(data, name, "second"))

    def two_calls(self, first: Call, phase: str, second: Call) -> None:
        assert self.part is not None
        before = self.snapshot()
        fired = len(self.part.fired)
        self.part.slow_next = {phase: SLOW}
        entered = self.part.slow_entered = asyncio.Event()

        async def both() -> tuple[asyncio.Task[Outcome], Outcome]:
            one = asyncio.ensure_future(self.invoke(first))
            stalled = asyncio.ensure_future(entered.wait())
            await asyncio.wait({one, stalled}, return_when=asyncio.FIRST_COMPLETED)
            stalled.cancel()
            two = await self.invoke(second)
            # wait for the first call, and for a pending run() that resume
            # started, to finish, unless they are a run() now paused
            loop = asyncio.get_running_loop()
            deadline = loop.time() + 2.0
            runs = {one} if first.name == "run" else set()
            if self.pending_run is not None:
                runs.add(self.pending_run)
            while loop.time() < deadline:
                busy = {f for f in {one, *runs} if not f.done()}
                if not busy or (busy <= runs and self.current == "Paused"):
                    break
                await asyncio.wait(busy, timeout=0.005)
            return one, two

        one_task, two = self.run(both())
        event(f"{second.name} in {two.state} during {first.name}")
        self.part.slow_next = {}
        self.part.slow_entered = None
        faulted = len(self.part.fired) > fired

        # the second call: refused exactly where the model says (or because
        # the first is still in progress in a state that allows it)
        if not self.allowed(second, two.state):
            assert isinstance(two.error, NotAllowedError), two
            assert two.state in str(two.error), two
        elif isinstance(two.error, NotAllowedError):
            assert second.name not in INTERRUPTS, two
            assert "in progress" in str(two.error), two

        if not one_task.done():
            # only a run() paused mid-way may still be waiting
            assert first.name == "run" and self.current == "Paused", (
                f"{first} did not finish; state {self.current} (path {self.states})"
            )
            assert second.name == "pause" and two.error is None, two
            self.pending_run = one_task
            return
        self.reap_pending_run()
        one = one_task.result()
        for call, out in ((first, one), (second, two)):
            if call.name == "configure" and out.error is None:
                self.scan = call.scan
        if not self.allowed(first, one.state):
            self.check_refused_loosely(one)
        if faulted:
            return  # the invariants check the fault
        if two.error is None and second.name in INTERRUPTS:
            assert self.current == INTERRUPTS[second.name], (
                f"{second} while {one} left the block {self.current}"
                f" (path {self.states[before['moves'] :]})"
            )
        for out in (one, two):
            assert out.error is None or isinstance(
                out.error, NotAllowedError | BadValueError | AbortedError
            ), f"{out} (path {self.states[before['moves'] :]})"
        if isinstance(one.error, AbortedError):
            assert two.name in INTERRUPTS, one
        if first.name == "run" and one.state == "Armed" and second.name in INTERRUPTS:
            if two.error is None and two.state in ("Running", "PostRun", "Paused"):
                assert isinstance(one.error, AbortedError), f"{one} after {two}"

    def check_refused_loosely(self, out: Outcome) -> None:
        assert isinstance(out.error, NotAllowedError), out
        assert out.state in str(out.error), out

    # ---- invariants
    @invariant()
    def moves_follow_the_model(self) -> None:
        for a, b in zip(self.states, self.states[1:]):
            assert b in self.moves[a], f"move {a} -> {b} is not in the model"

    @invariant()
    def phases_run_in_the_source_state(self) -> None:
        """Each phase runs in the source state of a transition that has it, and
        a move that has phases follows them: they are the last ones run in the
        source state. validate() runs Validate where the model allows it."""
        if self.part is None:
            return
        ran: dict[int, list[str]] = {}
        for phase, state, index in self.part.calls:
            assert self.states[index] == state, (phase, state, index, self.states)
            ran.setdefault(index, []).append(phase)
            sources = {t.source for t in self.model.transitions if phase in t.phases}
            assert state in sources, f"phase {phase} ran in state {state}"
        for phase, state in self.part.queries:
            assert phase == "Validate", f"validate() ran phase {phase}"
            assert self.model.allows("validate", state), f"validate() ran in {state}"
        for i, (a, b) in enumerate(zip(self.states, self.states[1:])):
            options = [
                t.phases for t in self.model.transitions if (t.source, t.dest) == (a, b)
            ]
            got = ran.get(i, [])
            assert any(got[len(got) - len(p) :] == list(p) for p in options), (
                f"{a} -> {b} after phases {got}; the model says one of {options}"
            )

    @invariant()
    def rests_healthy(self) -> None:
        if self.ctrl is None:
            return
        state = self.current
        assert not self.model.states[state].busy, f"left busy in {state}"
        health = self.ctrl.health.value
        if state == "Fault":
            assert health != "OK"
        elif state != "Disabled":
            assert health == "OK", f"health {health!r} in {state}"
        self.reap_pending_run()

    def reap_pending_run(self) -> None:
        """A paused run() waits while Paused and ends once the block leaves."""
        state = self.current
        if state == "Paused":
            # only pausing a run() lands Paused, and that run() waits for resume
            assert self.pending_run is not None, "Paused, but no run() was paused"
            assert not self.pending_run.done(), "Paused, but no run() to resume"
        elif self.pending_run is not None:
            run = self.collect_pending_run()
            # it ends normally, aborted, or with the fault a part caused
            assert (
                run.error is None
                or isinstance(run.error, AbortedError)
                or f"part(s) {PROBE}" in str(run.error)
                or f"part {PROBE!r}" in str(run.error)
            ), f"{run}, now {state}"


class StatefulMachine(ControllerMachine):
    model_name = "stateful"


class ManagerBase(ControllerMachine):
    """What the manager and runnable machines share: a temporary designs
    directory, the design in snapshots, the manager calls for two at once."""

    model_name = "manager"
    DESIGNS = ("d1", "d2", "", "bad name!", "never_saved")

    def __init__(self) -> None:
        super().__init__()
        self.designs_dir = tempfile.mkdtemp(prefix="malcolm-machine-")

    def saved(self, design: str) -> bool:
        return (Path(self.designs_dir) / MRI / f"{design}.yaml").is_file()

    def teardown(self) -> None:
        try:
            super().teardown()
        finally:
            shutil.rmtree(self.designs_dir, ignore_errors=True)

    def manager_args(self) -> dict[str, Any]:
        return {
            "designs_dir": self.designs_dir,
            "phase_timeout": PHASE_TIMEOUT,
            # long phases (a run) have no default timeout: give them one
            "phase_timeouts": {
                p: PHASE_TIMEOUT for p in self.model.phases_tagged("long")
            },
            "model": self.model,
        }

    def make_controller(self, parts: list[Part]) -> Controller:
        return ManagerController(MRI, parts, **self.manager_args())

    def snapshot(self) -> dict[str, Any]:
        snap = super().snapshot()
        assert isinstance(self.ctrl, ManagerController)
        snap["design"] = self.ctrl.design.value
        return snap

    def call_names(self) -> list[str]:
        return [*super().call_names(), "save", "load", "design", "exports"]

    def draw_call(self, data: st.DataObject, name: str, label: str) -> Call:
        if name in ("save", "load", "design"):
            design = data.draw(st.sampled_from(self.DESIGNS), label=f"{label} design")
            if name == "design":
                return Call(name, design, put=True)
            return Call(name, {"design": design})
        if name == "exports":
            return Call(name, EMPTY_EXPORTS, put=True)
        return super().draw_call(data, name, label)


class ManagerMachine(ManagerBase):
    """Adds save and load of designs, an edit of the exports table (which
    goes through Disabled) and set_visible."""

    @rule(design=st.sampled_from(ManagerBase.DESIGNS))
    def save(self, design: str) -> None:
        before = self.snapshot()
        out = self.call(Call("save", {"design": design}))
        if out is None:
            return
        name = design or before["design"]
        if name in ("", "bad name!"):
            assert isinstance(out.error, BadValueError), out
            self.check_unchanged(before, "a refused save")
            return
        assert out.error is None, out
        assert self.saved(name), f"save({name!r}) wrote no file"
        self.expect_path(before, "Saving", "Ready")
        assert self.snapshot()["design"] == name

    @rule(design=st.sampled_from(ManagerBase.DESIGNS), put=st.booleans())
    def load(self, design: str, put: bool) -> None:
        """load(design), or a put of design (the same thing)."""
        before = self.snapshot()
        call = (
            Call("design", design, put=True)
            if put
            else Call("load", {"design": design})
        )
        out = self.call(call)
        if out is None:
            return
        if not design or not self.saved(design):
            assert isinstance(out.error, BadValueError), out
            self.check_unchanged(before, "a refused load")
            return
        assert out.error is None, out
        self.expect_path(before, "Loading", "Ready")
        assert self.snapshot()["design"] == design

    @rule()
    def edit_exports(self) -> None:
        """A put of the exports table: the manager goes through Disabled."""
        before = self.snapshot()
        out = self.call(Call("exports", EMPTY_EXPORTS, put=True))
        if out is None:
            return
        assert out.error is None, out
        self.expect_path(before, "Disabling", "Disabled")

    @rule(visible=st.booleans())
    def set_visible_of_no_child(self, visible: bool) -> None:
        before = self.snapshot()
        out = self.call(Call("set_visible", {"block_name": "NOPE", "visible": visible}))
        if out is None:
            return
        assert isinstance(out.error, BadValueError), out
        self.check_unchanged(before, "a refused set_visible")


EMPTY_EXPORTS = {"name": [], "source": [], "description": []}


class RunnableMachine(ManagerBase):
    """The scan calls; the manager calls only in two_calls_at_once (the
    manager machine covers them one at a time)."""

    model_name = "runnable_device"
    runnable = True

    def make_controller(self, parts: list[Part]) -> Controller:
        det = SimDetectorPart("det", default_exposure=STEP_TIME)
        return RunnableController(MRI, [*parts, det], **self.manager_args())

    def stepping_phase(self) -> str | None:
        return "Run"

    def call_names(self) -> list[str]:
        return [
            *super().call_names(),
            *("configure", "validate", "run", "pause", "resume", "abort"),
            "completedSteps",
        ]

    def draw_call(self, data: st.DataObject, name: str, label: str) -> Call:
        if name in ("configure", "validate"):
            scan = data.draw(scans(), label=f"{label} scan")
            return Call(name, scan.params, scan=scan)
        if name == "pause":
            step = data.draw(st.integers(-1, 7), label=f"{label} lastGoodStep")
            return Call(name, {"lastGoodStep": step})
        if name == "completedSteps":
            step = data.draw(st.integers(-1, 7), label=f"{label} completedSteps")
            return Call(name, step, put=True)
        return super().draw_call(data, name, label)

    def clamp(self, n: int | None) -> int:
        completed, _, total = self.steps()
        return completed if n is None else max(0, min(n, total))

    def next_end(self, completed: int) -> int:
        assert self.scan is not None
        return self.scan.next_end(completed)

    # ---- invariants
    @invariant()
    def steps_are_ordered(self) -> None:
        if self.ctrl is None:
            return
        completed, configured, total = self.steps()
        assert 0 <= completed <= configured <= total, self.steps()
        state = self.current
        if state == "Armed":
            assert completed < configured, f"Armed with nothing to run: {self.steps()}"
        if state == "Finished":
            assert completed == total, f"Finished at {self.steps()}"

    # ---- rules
    @in_state("Ready", "Armed", "Finished", "Paused")
    @rule(data=st.data())
    def interrupt_a_scan_call(self, data: st.DataObject) -> None:
        """configure, run, pause, resume or a seek stalls in one of its phases
        while another call (most often abort, disable or pause) is made."""
        scan_calls = ("configure", "run", "pause", "resume", "completedSteps")
        names = [n for n in self.allowed_now() if n in scan_calls]
        name = data.draw(st.sampled_from(names), label="first")
        first = self.draw_call(data, name, "first")
        phase = data.draw(st.sampled_from(self.phases_of_call(name)), label="stall")
        name = data.draw(
            st.sampled_from(self.interrupts()) | st.sampled_from(self.call_names()),
            label="second",
        )
        self.two_calls(first, phase, self.draw_call(data, name, "second"))

    @rule(scan=scans())
    def configure(self, scan: Scan) -> None:
        before = self.snapshot()
        out = self.call(Call("configure", scan.params, scan=scan))
        if out is None:
            return
        if not scan.valid:
            assert isinstance(out.error, BadValueError), out
            self.check_unchanged(before, "a refused configure")
            return
        assert out.error is None, out
        self.scan = scan
        self.expect_path(before, "Configuring", "Armed")
        assert self.steps() == (0, scan.next_end(0), scan.total), self.steps()

    @rule(scan=scans())
    def validate(self, scan: Scan) -> None:
        before = self.snapshot()
        out = self.call(Call("validate", scan.params, scan=scan))
        if out is None:
            return
        if not scan.valid:
            assert isinstance(out.error, BadValueError), out
        else:
            assert out.error is None, out
            assert out.result["generator"] == scan.params["generator"], out
        self.check_unchanged(before, "validate()")

    # rules that make the scan go on more often than a random walk would
    @in_state("Ready", "Finished")
    @rule(scan=scans(valid_only=True))
    def configure_when_idle(self, scan: Scan) -> None:
        self.configure(scan)

    @in_state("Armed")
    @rule()
    def run_when_armed(self) -> None:
        self.run_once()

    @in_state("Paused")
    @rule()
    def resume_when_paused(self) -> None:
        self.resume()

    @in_state("Armed")
    @rule(
        data=st.data(),
        how=st.sampled_from(["pause", "pause", "abort", "disable"]),
        step=st.integers(-1, 7),
    )
    def interrupt_a_run(self, data: st.DataObject, how: str, step: int) -> None:
        """run() stalls while Running; pause (-> Paused, run() pending),
        abort or disable meanwhile."""
        running = [
            p for t in self.model.transitions_for("done", "Running") for p in t.phases
        ]
        phase = data.draw(st.sampled_from(running), label="stall")
        second = Call(how, {"lastGoodStep": step} if how == "pause" else None)
        self.two_calls(Call("run"), phase, second)

    @rule(scan=scans(valid_only=True), data=st.data())
    def scan_session(self, scan: Scan, data: st.DataObject) -> None:
        """From wherever: reset if need be, configure, then a few scan calls
        (runs, pauses, seeks, resumes, interrupted runs, failures, aborts),
        each checked as by its own rule. A random walk alone seldom gets
        this far into a scan."""
        if self.current in ("Fault", "Disabled", "Aborted", "Armed", "Finished"):
            self.reset()
        if self.current != "Ready":
            return
        self.configure(scan)
        steps = st.none() | st.integers(-2, 8)
        for _ in range(data.draw(st.integers(1, 10), label="calls")):
            if self.current not in ("Armed", "Paused", "Finished"):
                return
            what = data.draw(st.sampled_from(SESSION_CALLS), label="call")
            if what == "run":
                self.run_once()
            elif what == "pause":
                name = data.draw(st.sampled_from(["lastGoodStep", "completedSteps"]))
                self.pause(data.draw(steps, label="step"), name)
            elif what == "seek":
                self.put_completed_steps(data.draw(st.integers(-1, 7), label="step"))
            elif what == "resume":
                self.resume()
            elif what == "interrupt_a_run":
                how = data.draw(st.sampled_from(["pause", "pause", "abort", "disable"]))
                step = data.draw(st.integers(-1, 7), label="step")
                self.interrupt_a_run(data, how, step)
            elif what == "interrupt_a_scan_call":
                self.interrupt_a_scan_call(data)
            elif what == "validate":
                self.validate(data.draw(scans(), label="scan"))
            elif what == "misbehave":
                self.misbehave(data, "fail")
            else:
                getattr(self, what)()

    @rule()
    def run_once(self) -> None:
        before = self.snapshot()
        out = self.call(Call("run"))
        if out is None:
            return
        assert out.error is None, out
        _, configured, total = before["steps"]
        done = "Finished" if configured == total else "Armed"
        self.expect_path(before, "Running", "PostRun", done)
        assert self.steps() == (configured, self.next_end(configured), total)

    @rule(
        step=st.none() | st.integers(-2, 8),
        name=st.sampled_from(["lastGoodStep", "completedSteps"]),
    )
    def pause(self, step: int | None, name: str) -> None:
        before = self.snapshot()
        out = self.call(Call("pause", {} if step is None else {name: step}))
        if out is None:
            return
        assert out.error is None, out
        self.check_sought(before, self.clamp_from(before, step))

    def clamp_from(self, before: dict[str, Any], n: int | None) -> int:
        """Where pause(n) goes, as the reference's pause does: a negative
        step is the current one, one at or past the end the last step, and
        a pause that lands Paused does not land on the end of the run."""
        completed, configured, total = before["steps"]
        step = completed if n is None or n < 0 else min(n, total - 1)
        if before["state"] == "Paused" and step == configured:
            step -= 1
        return max(0, step)

    def check_sought(self, before: dict[str, Any], step: int) -> None:
        total = before["steps"][2]
        if before["state"] == "Paused":
            end = "Paused"
        else:
            end = "Finished" if step == total else "Armed"
        self.expect_path(before, "Seeking", end)
        assert self.steps() == (step, self.next_end(step), total), self.steps()

    @rule(step=st.integers(-2, 8))
    def put_completed_steps(self, step: int) -> None:
        before = self.snapshot()
        out = self.call(Call("completedSteps", step, put=True))
        if out is None:
            return
        if not 0 <= step <= before["steps"][2]:
            assert isinstance(out.error, BadValueError), out
            self.check_unchanged(before, "a refused put")
            return
        assert out.error is None, out
        self.check_sought(before, step)

    @rule()
    def resume(self) -> None:
        before = self.snapshot()
        out = self.call(Call("resume"))
        if out is None:
            return
        assert out.error is None, out  # the outcome of the pending run()
        _, configured, total = before["steps"]
        done = "Finished" if configured == total else "Armed"
        self.expect_path(before, "Running", "PostRun", done)
        assert self.steps() == (configured, self.next_end(configured), total)

    @rule()
    def abort(self) -> None:
        before = self.snapshot()
        pending = self.pending_run
        out = self.call(Call("abort"))
        if out is None:
            return
        assert out.error is None, out
        self.expect_path(before, "Aborting", "Aborted")
        if pending is not None:
            assert pending.done(), "run() still pending"
            assert isinstance(pending.result().error, AbortedError), pending.result()


class AreaDetectorMachine(RunnableMachine):
    model_name = "area_detector_runnable_device"

    def make_controller(self, parts: list[Part]) -> Controller:
        return RunnableController(MRI, parts, **self.manager_args())

    def stepping_phase(self) -> str | None:
        return "Running"


TestStatefulController = StatefulMachine.TestCase
TestStatefulController.settings = _settings(30)
TestManagerController = ManagerMachine.TestCase
TestManagerController.settings = _settings(30)
TestRunnableController = RunnableMachine.TestCase
TestRunnableController.settings = _settings(60)
TestAreaDetectorController = AreaDetectorMachine.TestCase
TestAreaDetectorController.settings = _settings(40)

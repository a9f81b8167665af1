"""The hypothesis machine every live controller gets (any model).

Each example builds a :class:`~malcolm.conformance.live.LiveBlock` for the
model (its controller class, three recorder parts) on its own loop. Rules
call what the model knows in ANY state, one at a time or two at once (the
first stalls in a chosen phase while the second is issued), and script
part failures and hangs. Checked throughout, by role and from the model:

* the states passed through form a path of ``model.moves()``, and every
  move ran its transition's phases (the model's, or a reference table's);
  every hook of a phase returned before the next phase or move;
* a call or put the model does not allow raises NotAllowedError naming
  the state and changes nothing;
* after every rule the block rests, health is OK outside the fault and
  disabled states;
* an injected part failure or phase timeout ends in the fault state with
  the part and the phase named in ``health``; reset from it returns to the
  ready state; abort and disable make a pending ``run()`` fail.
"""

from __future__ import annotations

import asyncio
import itertools
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar

from hypothesis import event
from hypothesis import strategies as st
from hypothesis.stateful import (
    RuleBasedStateMachine,
    initialize,
    invariant,
    precondition,
    rule,
)

from malcolm.core import AbortedError, BadValueError, NotAllowedError, PhaseTimeoutError
from malcolm.fsm import Model

from ..checks import Expected, hook_problems, phase_problems
from ..live import LiveBlock, Outcome
from ..recorder import RecorderPart

PHASE_TIMEOUT = 0.5  # a hung phase faults after this long (a healthy one, starved
# of CPU on a loaded machine, took over 0.2 s in full runs and faulted)
CALL_TIMEOUT = 5.0  # a call taking longer than this is a hang (test failure)
#: interrupting calls and the role of the state they end in
INTERRUPTS = {"abort": "aborted", "disable": "disabled"}


@dataclass(frozen=True)
class Call:
    name: str  # a method, or an attribute for a put
    params: Any = None  # method arguments, or the value put
    put: bool = False
    scan: Any = None  # for configure and validate: the Scan drawn

    def __repr__(self) -> str:
        if self.put:
            return f"put {self.name}={self.params!r}"
        return f"{self.name}({self.params or ''})"


def in_role(*roles: str) -> Callable[[Any], Any]:
    """A precondition: the block rests in a state with one of ``roles``."""
    return precondition(lambda self: self.block is not None and self.role in roles)


class ControllerMachine(RuleBasedStateMachine):
    """Common rules: reset, disable, failures, hangs and concurrent calls.

    Subclasses are made per model by :func:`malcolm.conformance.machines.
    machine_for`, which sets ``model`` (and ``expected``: the phases each
    transition must run, when a reference table says).
    """

    model: ClassVar[Model]
    expected: ClassVar[Expected | None] = None
    runnable: ClassVar[bool] = False

    def __init__(self) -> None:
        super().__init__()
        self.moves = self.model.moves()
        self.block: LiveBlock | None = None
        self.pending_run: asyncio.Task[Outcome] | None = None

    # ---- set up and tear down
    def extra_parts(self) -> list[Any]:
        return []

    @initialize(fail_init=st.integers(0, 3).map(lambda n: n == 3))
    def start(self, fail_init: bool) -> None:
        block = self.block = LiveBlock(
            self.model, phase_timeout=PHASE_TIMEOUT, extra_parts=self.extra_parts()
        )
        init = self.model.transitions_for("init", self.model.initial)
        phases = [p for t in init for p in t.phases]
        if fail_init and phases:
            self.part.fail_next.add(phases[0])
        block.start()
        if fail_init and phases:
            # Init runs while the block is still in its initial state; with
            # no move from there to the fault state it stays there, with
            # the failure in health (the process still starts).
            if self.model.transitions_for("fault", self.model.initial):
                assert self.role == "fault", self.states
            else:
                assert self.states == [self.model.initial], self.states
            self.check_health_names(phases[0])
        else:
            want = self.paths(self.model.initial, "init", {})
            assert self.states[1:] in want, f"start went {self.states}, not {want}"

    def teardown(self) -> None:
        if self.block is not None:
            self.block.close()

    # ---- the block
    @property
    def part(self) -> RecorderPart:
        """The recorder that misbehaves when told to."""
        assert self.block is not None
        return self.block.recorders[0]

    @property
    def ctrl(self) -> Any:
        assert self.block is not None
        return self.block.ctrl

    @property
    def states(self) -> list[str]:
        assert self.block is not None
        return self.block.path

    @property
    def current(self) -> str:
        assert self.block is not None
        return self.block.state

    @property
    def role(self) -> str | None:
        return self.model.role_of(self.current)

    def state_of(self, role: str) -> str:
        return self.model.state_for(role)

    def at(self, state: str) -> str:
        """Where the model declares ``state`` (file:line)."""
        file, line = self.model.where("state", state)
        return f"{file}:{line}" if line else file

    def run(self, coro: Any, timeout: float = CALL_TIMEOUT) -> Any:
        assert self.block is not None
        return self.block.run(coro, timeout)

    async def invoke(self, call: Call) -> Outcome:
        """Make a call; the state is read in the same step the call checks it."""
        assert self.block is not None
        return await self.block.invoke(call.name, call.params, call.put)

    def allowed(self, call: Call, state: str) -> bool:
        if call.put:
            return self.model.put_allowed(call.name, state)
        return self.model.allows(call.name, state)

    def snapshot(self) -> dict[str, Any]:
        return {
            "state": self.current,
            "health": self.ctrl.health.value,
            "moves": len(self.states),
        }

    # ---- expected paths, from the model
    def paths(
        self, state: str, trigger: str, guards: dict[str, bool]
    ) -> list[list[str]]:
        """Every path ``trigger`` may take from ``state`` through busy states,
        with the ``guards`` given and any other guard either way."""
        unknown = sorted(self.model.guards() - set(guards))
        found: list[list[str]] = []
        for values in itertools.product([False, True], repeat=len(unknown)):
            answers = {**guards, **dict(zip(unknown, values))}
            path = self._walk(state, trigger, answers)
            if path is not None and path not in found:
                found.append(path)
        return found

    def _walk(
        self, state: str, trigger: str, answers: dict[str, bool]
    ) -> list[str] | None:
        path: list[str] = []
        ts = self.model.transitions_for(trigger, state)
        while True:
            t = next(
                (
                    t
                    for t in ts
                    if all(answers[g] for g in t.guards)
                    and not any(answers[g] for g in t.unless)
                ),
                None,
            )
            if t is None:
                return path if path else None
            path.append(t.dest)
            if not self.model.states[t.dest].busy or len(path) > 50:
                return path
            ts = self.model.transitions_for("done", t.dest)

    def expect_walk(self, before: dict[str, Any], trigger: str, **guards: bool) -> None:
        got = self.states[before["moves"] :]
        want = self.paths(before["state"], trigger, guards)
        assert got in want, (
            f"{trigger} from {before['state']} went {got}; model {self.model.name}"
            f" ({self.model.path}) says {' or '.join(map(str, want))}"
        )

    # ---- one call at a time
    def call(self, call: Call) -> Outcome | None:
        """Make ``call`` and check what the model says about it.

        Returns the outcome for the rule to check further, or None when
        there is nothing more to check (refused as the model says, or a
        scripted failure took over).
        """
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
            f"model {self.model.name} ({self.model.path}) allows {call} in"
            f" {out.state}, but it was refused: {out}"
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
            f"model {self.model.name} ({self.model.path}) does not allow"
            f" {out.name} in {out.state}: {out}"
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
        health = self.ctrl.health.value
        assert self.part.name in health and phase in health, (
            f"health {health!r} does not name part {self.part.name!r} and"
            f" phase {phase!r}"
        )

    def ran_in(self, phase: str) -> str | None:
        """The state the last run of ``phase`` (own device) started in."""
        assert self.block is not None
        for e in reversed(self.block.log):
            if e.kind == "start" and e.own and e.phase == phase:
                return e.state
        return None

    def check_fault(
        self, out: Outcome, fired: list[tuple[str, str]], call: Call | None
    ) -> None:
        """A scripted failure or hang happened during ``out``."""
        phase, how = fired[-1]
        if call is not None and call.name == "validate":
            # validate() is a query: a failing Validate phase is its error
            # alone; the block does not fault
            assert out.error is not None, out
            assert self.current == out.state, (out, self.states)
            return
        where = self.ran_in(phase)
        if where is not None and not self.model.transitions_for("fault", where):
            return  # no move to the fault state from there
        if where is not None and not self.model.states[where].busy:
            # a phase run before the block leaves a resting state: its
            # failure is the call's error; the block either faults or (issue
            # 7 item 8) stays where it was, since nothing moved
            assert out.error is not None, f"{out} hid a part failure in {phase}"
            if self.current == out.state:
                return
        assert self.role == "fault", (
            f"a part failure ({how} in {phase}) during {out} left the block"
            f" {self.current}, not in its fault state (path {self.states})"
        )
        assert out.error is not None, f"{out} hid a part failure ({how} in {phase})"
        if how == "hang":
            assert isinstance(out.error, PhaseTimeoutError), out
        self.check_health_names(phase)

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
        self.expect_walk(before, "reset")
        assert self.ctrl.health.value == "OK", self.ctrl.health.value

    @rule()
    def disable(self) -> None:
        before = self.snapshot()
        pending = self.pending_run
        out = self.call(Call("disable"))
        if out is None:
            return
        assert out.error is None, out
        self.expect_walk(before, "disable")
        if pending is not None:
            assert pending.done(), "run() still pending"
            assert isinstance(pending.result().error, AbortedError), pending.result()

    @rule(data=st.data(), how=st.sampled_from(["fail", "fail", "hang", "behave"]))
    def misbehave(self, data: st.DataObject, how: str) -> None:
        """A recorder raises (fail) or hangs until the phase timeout (hang) the
        next time it runs the chosen phase; or stops doing either (behave)."""
        if how == "behave":
            self.part.fail_next.clear()
            self.part.hang_next.clear()
            return
        phase = data.draw(st.sampled_from(sorted(self.model.phases)), label="phase")
        (self.part.fail_next if how == "fail" else self.part.hang_next).add(phase)

    @rule(data=st.data())
    def other_model_call(self, data: st.DataObject) -> None:
        """A call of the model that no rule knows (a user model's own), with
        no arguments: refused where the model says, never a hang."""
        names = self.other_calls()
        if not names:
            return
        name = data.draw(st.sampled_from(names), label="call")
        out = self.call(Call(name))
        if out is not None and out.error is not None:
            assert isinstance(out.error, BadValueError | AbortedError), out

    def other_calls(self) -> list[str]:
        """Calls of the model the block has and no rule knows."""
        known = set(self.known_calls()) | {"validate", "set_visible", "set_position"}
        block = self.ctrl.block
        return sorted(
            n for n in self.model.methods if n not in known and n in block.methods
        )

    # ---- two calls at once
    def known_calls(self) -> list[str]:
        """The calls and puts (by attribute name) the rules know."""
        return ["reset", "disable"]

    def call_names(self) -> list[str]:
        """Every call and put the block has."""
        return [*self.known_calls(), *self.other_calls()]

    def draw_call(self, data: st.DataObject, name: str, label: str) -> Call:
        return Call(name, put=name in self.model.attributes)

    def phases_of_call(self, name: str) -> list[str]:
        """The phases ``name`` may run: those of its trigger's transitions and
        of the ``done`` moves out of the busy states they lead to."""
        rule = self.model.attributes.get(name)
        trigger = rule.trigger if rule is not None else name
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
        assert self.block is not None
        before = self.snapshot()
        fired = len(self.part.fired)
        release = self.block.stall(phase)
        slowest = self.block.recorders[-1]
        stalled = slowest.stalled

        async def both() -> tuple[asyncio.Task[Outcome], Outcome]:
            one = asyncio.ensure_future(self.invoke(first))
            entered = asyncio.ensure_future(stalled.wait())
            await asyncio.wait({one, entered}, return_when=asyncio.FIRST_COMPLETED)
            entered.cancel()
            slowest.stall.pop(phase, None)  # the stall is for the first call only
            two = await self.invoke(second)
            release.set()
            # wait for the first call, and for a pending run() that resume
            # started, to finish, unless they are a run() now paused
            runs = {one} if first.name == "run" else set()
            if self.pending_run is not None:
                runs.add(self.pending_run)
            loop = asyncio.get_running_loop()
            deadline = loop.time() + 2.0
            while loop.time() < deadline:
                busy = {f for f in {one, *runs} if not f.done()}
                if not busy or (busy <= runs and self.role == "paused"):
                    break
                await asyncio.wait(busy, timeout=0.005)
            return one, two

        one_task, two = self.run(both())
        event(f"{second.name} in {two.state} during {first.name}")
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
            assert first.name == "run" and self.role == "paused", (
                f"{first} did not finish; state {self.current} (path {self.states})"
            )
            assert second.name == "pause" and two.error is None, two
            self.pending_run = one_task
            return
        self.reap_pending_run()
        one = one_task.result()
        self.after_two_calls(first, one, second, two)
        if not self.allowed(first, one.state):
            assert isinstance(one.error, NotAllowedError), one
            assert one.state in str(one.error), one
        if faulted:
            return  # the invariants check the fault
        if two.error is None and second.name in INTERRUPTS:
            assert self.role == INTERRUPTS[second.name], (
                f"{second} while {one} left the block {self.current}"
                f" (path {self.states[before['moves'] :]})"
            )
        for out in (one, two):
            assert out.error is None or isinstance(
                out.error, NotAllowedError | BadValueError | AbortedError
            ), f"{out} (path {self.states[before['moves'] :]})"
        if isinstance(one.error, AbortedError):
            assert two.name in INTERRUPTS, one

    def after_two_calls(
        self, first: Call, one: Outcome, second: Call, two: Outcome
    ) -> None:
        """What a subclass learns from two calls at once (a runnable: the scan)."""

    # ---- invariants
    @invariant()
    def moves_follow_the_model(self) -> None:
        if self.block is None:
            return
        states = self.states
        for a, b in zip(states, states[1:]):
            assert b in self.moves[a], (
                f"moved {a} -> {b}, which model {self.model.name}"
                f" ({self.model.path}) does not have"
            )

    @invariant()
    def moves_run_their_phases(self) -> None:
        """Each move ran its transition's phases (phase_problems), every hook
        returned before the next phase or move (hook_problems), and
        validate() ran only phases of the validate call."""
        if self.block is None:
            return
        log = self.block.log
        problems = phase_problems(log, self.model, type(self).expected)
        problems += hook_problems(log, resting=self.role != "paused")
        assert not problems, "\n".join(problems)
        for e in log:
            if e.kind == "start" and not e.own:
                assert e.phase in self.phases_of_call("validate"), (
                    f"validate() ran phase {e.phase}"
                )
                assert self.model.allows("validate", e.state), (
                    f"validate() ran in {e.state}"
                )

    @invariant()
    def rests_healthy(self) -> None:
        if self.block is None:
            return
        state = self.current
        assert not self.model.states[state].busy, (
            f"{self.at(state)}: the block was left in busy state {state}"
        )
        health = self.ctrl.health.value
        if self.role == "fault":
            assert health != "OK", f"{self.at(state)}: {state}, but health is OK"
        elif self.role != "disabled":
            assert health == "OK", f"{self.at(state)}: health {health!r} in {state}"
        self.reap_pending_run()

    def reap_pending_run(self) -> None:
        """A paused run() waits while paused and ends once the block leaves."""
        if self.role == "paused":
            # only pausing a run() lands paused, and that run() waits for resume
            assert self.pending_run is not None, "Paused, but no run() was paused"
            assert not self.pending_run.done(), "Paused, but no run() to resume"
        elif self.pending_run is not None:
            run = self.collect_pending_run()
            # it ends normally, aborted, or with the fault a part caused
            part = self.part.name
            assert (
                run.error is None
                or isinstance(run.error, AbortedError)
                or f"part(s) {part}" in str(run.error)
                or f"part {part!r}" in str(run.error)
            ), f"{run}, now {self.current}"

"""Scripted calls that take a live controller through every transition that
runs phases, checking the recorder log after each call.

The script depends on the controller class the model names: every
controller gets start, disable, reset and a part failure; a manager also
save and load; a runnable device a scan in two runs with pauses (from
Armed, Paused, Finished and a stalled run), seeks, resume, abort, a failed
run and a disable during a run. Calls are by name and states by role
(``ready``, ``armed``, ...), so a model may name its states as it likes.

After each call the block must rest in the state the script expects, and
the log must pass :func:`~malcolm.conformance.checks.phase_problems` (each
move ran its transition's phases, the model's or a reference table's),
:func:`~malcolm.conformance.checks.hook_problems` and
:func:`~malcolm.conformance.checks.progress_problems`. The first call that
fails ends the script: what follows would only repeat it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, NoReturn

from malcolm.fsm import Model

from .checks import (
    Expected,
    hook_problems,
    observed_moves,
    phase_problems,
    progress_problems,
)
from .live import LiveBlock, Outcome, run_phases

DESIGN = "conformance"
POINTS = 4  # a line scan of 4 points, cut into two runs of 2


def scan(size: int = POINTS) -> dict[str, Any]:
    """A CompoundGenerator of one line of ``size`` points, as GDA sends it."""
    line = {
        "typeid": "scanpointgenerator:generator/LineGenerator:1.0",
        "axes": ["x"],
        "units": ["mm"],
        "start": [0.0],
        "stop": [1.0],
        "size": size,
        "alternate": False,
    }
    return {
        "typeid": "scanpointgenerator:generator/CompoundGenerator:1.0",
        "generators": [line],
        "excluders": [],
        "mutators": [],
        "duration": 0.001,
    }


class StopScript(Exception):
    """A call went wrong: the script ends there."""


@dataclass
class Report:
    """What the script found, and which transitions it saw taken."""

    problems: list[str] = field(default_factory=list)
    #: (trigger, source, dest) of every move seen
    covered: set[tuple[str, str, str]] = field(default_factory=set)
    steps: list[str] = field(default_factory=list)


class Script:
    """Makes the calls and checks each; problems go into ``report``."""

    def __init__(self, block: LiveBlock, expected: Expected | None) -> None:
        self.block = block
        self.model: Model = block.model
        self.expected = expected
        self.report = Report()
        self.run_phases = run_phases(self.model)

    def state_of(self, role: str) -> str:
        try:
            return self.model.state_for(role)
        except KeyError as e:
            self.fail(f"the script needs a state with role {role!r}: {e}")

    def fail(self, problem: str) -> NoReturn:
        self.report.problems.append(problem)
        raise StopScript(problem)

    def check(
        self,
        step: str,
        out: Outcome | None,
        rests_in: str,
        error: bool = False,
    ) -> None:
        """After ``step``: the outcome, the state, and the whole log so far."""
        self.report.steps.append(step)
        found: list[str] = []
        if out is not None and (out.error is not None) != error:
            want = "an error" if error else "no error"
            found.append(f"expected {want}, but {out!r}")
        target = self.state_of(rests_in)
        if self.block.state != target:
            found.append(
                f"ended in {self.block.state} (health: {self.block.health}),"
                f" not {target} (role {rests_in})"
            )
        log = self.block.log
        found += phase_problems(log, self.model, self.expected)
        found += hook_problems(log)
        found += progress_problems(log, self.model, self.run_phases)
        for move in observed_moves(log, self.model):
            if move.transition is not None:
                t = move.transition
                self.report.covered.add((t.trigger, t.source, t.dest))
        if found:
            self.report.problems += [f"after {step}: {p}" for p in found]
            raise StopScript(step)

    # ---- helpers
    def phases_after(self, trigger: str, source: str) -> list[str]:
        """The phases a call runs from ``source``: its transition's, then
        those of the ``done`` moves until the block rests (unguarded ones)."""
        phases: list[str] = []
        ts = self.model.transitions_for(trigger, source)
        for _ in range(len(self.model.states)):  # done may cycle: stop somewhere
            if not ts:
                break
            t = ts[-1]
            phases += t.phases
            if not self.model.states[t.dest].busy:
                break
            ts = self.model.transitions_for("done", t.dest)
        return phases

    def call(
        self, name: str, rests_in: str, error: bool = False, **params: Any
    ) -> Outcome:
        shown = ", ".join(f"{k}={v!r}" for k, v in params.items() if k != "generator")
        if "generator" in params:
            shown = ", ".join(filter(None, ["generator", shown]))
        out = self.block.call(name, **params)
        self.check(f"{name}({shown})", out, rests_in, error)
        return out

    def put(self, name: str, value: Any, rests_in: str) -> Outcome:
        out = self.block.put(name, value)
        self.check(f"put {name}={value!r}", out, rests_in)
        return out

    def fail_phase(self, phase: str) -> None:
        self.block.recorders[0].fail_next.add(phase)

    def health_names(self, phase: str) -> None:
        part = self.block.recorders[0].name
        health = self.block.health
        if part not in health or phase not in health:
            self.fail(
                f"health {health!r} does not name part {part!r} and phase {phase!r}"
            )


# --------------------------------------------------------------------------
# The scripts


def stateful_script(s: Script) -> None:
    """start, disable, reset, a failure in a reset phase, reset, disable."""
    s.block.start()
    s.check("start (init)", None, "ready")
    s.call("disable", "disabled")
    s.call("reset", "ready")
    s.call("disable", "disabled")
    phases = s.phases_after("reset", s.state_of("disabled"))
    if phases:
        s.fail_phase(phases[-1])
        s.call("reset", "fault", error=True)
        s.health_names(phases[-1])
        s.call("reset", "ready")
        s.fail_phase(phases[-1])
        s.call("disable", "disabled")
        s.call("reset", "fault", error=True)
        s.call("disable", "disabled")
    s.call("reset", "ready")


def manager_script(s: Script) -> None:
    """save, load, and a put of design (which loads)."""
    s.call("save", "ready", design=DESIGN)
    s.call("load", "ready", design=DESIGN)
    s.put("design", DESIGN, "ready")


def stalled_run(s: Script, then: str, rests_in: str, **params: Any) -> Any:
    """run() stalls in the run's last phase; ``then`` is called meanwhile.
    Returns run()'s task (done, unless ``then`` paused it)."""
    event = s.block.stall(s.run_phases[-1])
    pending = s.block.begin("run")
    s.block.wait_stalled()
    s.call(then, rests_in, **params)
    event.set()
    return pending


def runnable_script(s: Script) -> None:
    """A scan of 4 points in two runs, through every state that runs phases."""
    if not s.run_phases:
        s.fail("the model's running state has no done transition with phases")
    stepping = s.run_phases[-1]
    gen = scan()
    s.call("validate", "ready", generator=gen, breakpoints=[2, 2])
    s.call("configure", "armed", generator=gen, breakpoints=[2, 2])
    s.call("pause", "armed", lastGoodStep=1)  # pause from Armed: Seek -> Armed
    s.put("completedSteps", 0, "armed")  # seek from Armed
    s.call("run", "armed")  # steps 0..2, PostRunArmed
    # a run paused while it runs: Pause where it runs, Seek -> Paused
    pending = stalled_run(s, "pause", "paused", lastGoodStep=1)
    s.call("pause", "paused", lastGoodStep=2)  # from Paused
    s.put("completedSteps", 2, "paused")  # seek from Paused
    out = s.block.run(_resume_and_wait(s.block, pending))
    s.check("resume() of the paused run", out, "finished")  # PostRunReady
    s.call("pause", "armed", lastGoodStep=2)  # from Finished
    s.put("completedSteps", POINTS, "finished")  # Seeking -> Finished
    s.call("configure", "armed", generator=gen)  # from Finished
    s.call("abort", "aborted")
    s.call("reset", "ready")
    s.call("configure", "armed", generator=gen)
    run = s.block.finish(stalled_run(s, "abort", "aborted"))
    s.check("run() aborted while running", None, "aborted")
    if run.error is None:
        s.fail(f"run() should fail when aborted, but {run!r}")
    s.call("reset", "ready")
    s.call("configure", "armed", generator=gen)
    s.fail_phase(stepping)
    s.call("run", "fault", error=True)
    s.health_names(stepping)
    s.call("reset", "ready")
    s.call("configure", "armed", generator=gen)
    run = s.block.finish(stalled_run(s, "disable", "disabled"))
    if run.error is None:
        s.fail(f"run() should fail when disabled, but {run!r}")
    s.call("reset", "ready")


async def _resume_and_wait(block: LiveBlock, pending: Any) -> Outcome:
    out = await block.invoke("resume")
    if out.error is not None:
        return out
    return await pending


def run_script(model: Model, expected: Expected | None = None) -> Report:
    """Build a live controller for ``model`` and run the scripts its
    controller class gets; the report lists every problem found."""
    from malcolm.controllers.manager import ManagerController
    from malcolm.controllers.runnable import RunnableController

    block = LiveBlock(model)
    script = Script(block, expected)
    try:
        stateful_script(script)
        if issubclass(block.cls, ManagerController):
            manager_script(script)
        if issubclass(block.cls, RunnableController):
            runnable_script(script)
    except StopScript:
        pass
    except AssertionError as e:  # a call that hung
        script.report.problems.append(
            f"after {', '.join(script.report.steps[-1:]) or 'building it'}: {e}"
        )
    finally:
        block.close()
    return script.report

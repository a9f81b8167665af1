"""The hypothesis machine of a live runnable device's scan calls (configure,
validate, run, pause, seek, resume, abort), on top of the manager machine's
common rules. The steps move as interop.md section 1 says; states are
found by role and paths from the model."""

from __future__ import annotations

from typing import Any

from hypothesis import strategies as st
from hypothesis.stateful import invariant, rule

from malcolm.core import AbortedError, BadValueError

from ..live import Outcome, run_phases
from .base import Call, in_role
from .manager import ManagerBase
from .scans import STEP_TIME, Scan, scans

SESSION_CALLS = [
    *("run", "run", "run", "pause", "pause", "seek", "resume", "resume"),
    *("interrupt_a_run", "interrupt_a_run", "interrupt_a_scan_call"),
    *("validate", "misbehave", "abort", "disable", "reset"),
]


def pause_targets(
    requested: int | None,
    completed: int,
    configured: int,
    total: int,
    lands_paused: bool,
) -> set[int]:
    """Where pause(lastGoodStep=requested) may land: the step clamped to
    [0, total] (the controller before issue 7 item 5), or the reference's
    rule (item 5: a negative step is the current one, one at or past the end
    the last step, the current one of a Finished scan too, and a pause that
    lands Paused not on the end of the run)."""
    clamped = completed if requested is None else max(0, min(requested, total))
    step = completed if requested is None or requested < 0 else requested
    step = min(step, total - 1)
    if lands_paused and step == configured:
        step -= 1
    return {clamped, max(0, step)}


class RunnableMachine(ManagerBase):
    """The scan calls; the manager calls only in two_calls_at_once (the
    manager machine covers them one at a time)."""

    runnable = True

    def __init__(self) -> None:
        super().__init__()
        self.scan: Scan | None = None

    def extra_parts(self) -> list[Any]:
        """A simulated detector too, if the model has the phases it hooks."""
        from malcolm.parts.demo import SimDetectorPart

        det = SimDetectorPart("det", default_exposure=STEP_TIME)
        if all(phase in self.model.phases for phase, _ in det.hook_functions()):
            return [det]
        return []

    def snapshot(self) -> dict[str, Any]:
        snap = super().snapshot()
        snap["steps"] = self.steps()
        return snap

    def steps(self) -> tuple[int, int, int]:
        """(completed, configured, total)."""
        c = self.ctrl
        return (c.completed.value, c.configured.value, c.total.value)

    def known_calls(self) -> list[str]:
        return [
            *super().known_calls(),
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

    def after_two_calls(
        self, first: Call, one: Outcome, second: Call, two: Outcome
    ) -> None:
        for call, out in ((first, one), (second, two)):
            if call.name == "configure" and out.error is None:
                self.scan = call.scan
        if (
            first.name == "run"
            and self.model.is_state(one.state, "armed")
            and second.name in ("abort", "disable")
            and two.error is None
            and self.model.role_of(two.state) in ("running", "post_run", "paused")
        ):
            assert isinstance(one.error, AbortedError), f"{one} after {two}"

    def next_end(self, completed: int) -> int:
        assert self.scan is not None
        return self.scan.next_end(completed)

    # ---- invariants
    @invariant()
    def steps_are_ordered(self) -> None:
        if self.block is None:
            return
        completed, configured, total = self.steps()
        assert 0 <= completed <= configured <= total, self.steps()
        if self.role == "armed":
            assert completed < configured, f"Armed with nothing to run: {self.steps()}"
        if self.role == "finished":
            assert completed == total, f"Finished at {self.steps()}"

    # ---- rules
    @in_role("ready", "armed", "finished", "paused")
    @rule(data=st.data())
    def interrupt_a_scan_call(self, data: st.DataObject) -> None:
        """configure, run, pause, resume or a seek stalls in one of its phases
        while another call (most often abort, disable or pause) is made."""
        scan_calls = ("configure", "run", "pause", "resume", "completedSteps")
        names = [n for n in self.allowed_now() if n in scan_calls]
        if not names:
            return
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
        self.expect_walk(before, "configure")
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
    @in_role("ready", "finished")
    @rule(scan=scans(valid_only=True))
    def configure_when_idle(self, scan: Scan) -> None:
        self.configure(scan)

    @in_role("armed")
    @rule()
    def run_when_armed(self) -> None:
        self.run_once()

    @in_role("paused")
    @rule()
    def resume_when_paused(self) -> None:
        self.resume()

    @in_role("armed")
    @rule(
        data=st.data(),
        how=st.sampled_from(["pause", "pause", "abort", "disable"]),
        step=st.integers(-1, 7),
    )
    def interrupt_a_run(self, data: st.DataObject, how: str, step: int) -> None:
        """run() stalls in a phase of the run; pause (-> paused, run()
        pending), abort or disable meanwhile."""
        phase = data.draw(st.sampled_from(run_phases(self.model)), label="stall")
        second = Call(how, {"lastGoodStep": step} if how == "pause" else None)
        self.two_calls(Call("run"), phase, second)

    @rule(scan=scans(valid_only=True), data=st.data())
    def scan_session(self, scan: Scan, data: st.DataObject) -> None:
        """From wherever: reset if need be, configure, then a few scan calls
        (runs, pauses, seeks, resumes, interrupted runs, failures, aborts),
        each checked as by its own rule. A random walk alone seldom gets
        this far into a scan."""
        if self.role in ("fault", "disabled", "aborted", "armed", "finished"):
            self.reset()
        if self.role != "ready":
            return
        self.configure(scan)
        steps = st.none() | st.integers(-2, 8)
        for _ in range(data.draw(st.integers(1, 10), label="calls")):
            if self.role not in ("armed", "paused", "finished"):
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
        self.expect_walk(before, "run", scan_complete=configured == total)
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
        completed, configured, total = before["steps"]
        paused = self.model.is_state(before["state"], "paused")
        targets = pause_targets(step, completed, configured, total, paused)
        landed = self.steps()[0]
        assert landed in targets, (
            f"pause({name}={step}) from {before['steps']} went to step {landed},"
            f" not {' or '.join(map(str, sorted(targets)))}"
        )
        self.check_sought(before, "pause", landed)

    def check_sought(self, before: dict[str, Any], trigger: str, step: int) -> None:
        total = before["steps"][2]
        paused = self.model.is_state(before["state"], "paused")
        self.expect_walk(before, trigger, is_paused=paused, scan_complete=step == total)
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
        self.check_sought(before, "seek", step)

    @rule()
    def resume(self) -> None:
        before = self.snapshot()
        out = self.call(Call("resume"))
        if out is None:
            return
        assert out.error is None, out  # the outcome of the pending run()
        _, configured, total = before["steps"]
        self.expect_walk(before, "resume", scan_complete=configured == total)
        assert self.steps() == (configured, self.next_end(configured), total)

    @rule()
    def abort(self) -> None:
        before = self.snapshot()
        pending = self.pending_run
        out = self.call(Call("abort"))
        if out is None:
            return
        assert out.error is None, out
        self.expect_walk(before, "abort")
        if pending is not None:
            assert pending.done(), "run() still pending"
            assert isinstance(pending.result().error, AbortedError), pending.result()

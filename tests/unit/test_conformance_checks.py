"""The checks on a recorder log (malcolm.conformance.checks), on logs
written by hand: each finds what it is for, and nothing in a good log."""

from __future__ import annotations

from malcolm.conformance.checks import (
    hook_problems,
    observed_moves,
    phase_problems,
    progress_problems,
)
from malcolm.conformance.recorder import Event
from malcolm.fsm import load_model

RUNNABLE = load_model("runnable_device")


def call(name: str, trigger: str | None = None) -> Event:
    return Event("call", value=name, trigger=trigger)


def hooks(phase: str, state: str, parts: str = "ab", how: str = "ok") -> list[Event]:
    """Every part starts, then every part ends."""
    starts = [Event("start", p, phase, state) for p in parts]
    return starts + [Event("end", p, phase, value=how) for p in parts]


def move(a: str, b: str) -> Event:
    return Event("move", state=a, dest=b)


def configure() -> list[Event]:
    return [
        call("configure", "configure"),
        *hooks("ReportStatus", "Ready"),
        *hooks("Validate", "Ready"),
        move("Ready", "Configuring"),
        *hooks("PreConfigure", "Configuring"),
        *hooks("Configure", "Configuring"),
        *hooks("PostConfigure", "Configuring"),
        move("Configuring", "Armed"),
        Event("return", value="configure"),
    ]


def test_a_good_log_has_no_problems() -> None:
    log = configure()
    assert phase_problems(log, RUNNABLE) == []
    assert hook_problems(log) == []
    moves = observed_moves(log, RUNNABLE)
    assert [(m.transition.trigger, m.ran) for m in moves] == [
        ("configure", ("ReportStatus", "Validate")),
        ("done", ("PreConfigure", "Configure", "PostConfigure")),
    ]


def test_a_missing_phase_or_another_order_is_named() -> None:
    log = configure()
    del log[14:18]  # the Configure hooks
    (problem,) = phase_problems(log, RUNNABLE)
    assert problem.startswith("transition done Configuring->Armed (")
    assert problem.endswith(
        "should run [PreConfigure, Configure, PostConfigure], but the block ran"
        " [PreConfigure, PostConfigure] in Configuring before it moved"
    )
    swapped = configure()
    swapped[1:5], swapped[5:9] = swapped[5:9], swapped[1:5]
    (problem,) = phase_problems(swapped, RUNNABLE)
    assert "but the block ran [Validate, ReportStatus] in Ready" in problem


def test_the_table_decides_what_a_transition_should_run() -> None:
    def table(t):  # a reference that wants Configure before PreConfigure
        if t.phases == ("PreConfigure", "Configure", "PostConfigure"):
            return ("Configure", "PreConfigure", "PostConfigure")
        return t.phases

    (problem,) = phase_problems(configure(), RUNNABLE, table)
    assert "should run [Configure, PreConfigure, PostConfigure]" in problem


def test_a_phase_that_starts_before_the_last_one_ended() -> None:
    log = [
        Event("start", "a", "Init", "Disabled"),
        Event("start", "b", "Init", "Disabled"),
        Event("end", "a", "Init", value="ok"),
        move("Disabled", "Resetting"),
        Event("start", "a", "Reset", "Resetting"),
        Event("end", "b", "Init", value="ok"),
        Event("end", "a", "Reset", value="ok"),
    ]
    assert hook_problems(log) == [
        "moved Disabled -> Resetting while part 'b' was still running its Init hook",
        "phase Reset started while part 'b' was still running its Init hook: a"
        " phase must end only when all its hooks have returned",
    ]


def test_a_hook_that_never_returns() -> None:
    log = [Event("start", "a", "Init", "Disabled")]
    assert hook_problems(log) == ["part 'a''s Init hook never returned"]
    assert hook_problems(log, resting=False) == []


def test_a_cancelled_hook_needs_a_reason() -> None:
    log = hooks("Run", "Running", "a") + hooks("Run", "Running", "b", "cancelled")
    assert hook_problems(log) == [
        "part 'b''s Run hook was cancelled though no part failed or hung and no"
        " call interrupted it"
    ]
    during_a_call = [call("abort", "abort"), *log, Event("return", value="abort")]
    assert hook_problems(during_a_call) == []
    after_a_failure = [
        *hooks("Run", "Running", "a", "error"),
        *hooks("Run", "Running", "b", "cancelled"),
    ]
    assert hook_problems(after_a_failure) == []


def test_a_failed_or_cancelled_run_is_no_transitions_phases() -> None:
    log = [
        call("configure", "configure"),
        *hooks("ReportStatus", "Ready"),
        *hooks("Validate", "Ready", "a", "error"),
        move("Ready", "Fault"),
    ]
    (fault,) = observed_moves(log, RUNNABLE)
    assert fault.ran == ("ReportStatus",)
    assert phase_problems(log, RUNNABLE) == []


def test_progress_must_be_the_slowest_working_parts() -> None:
    start = [move("Armed", "Running"), Event("completed", value=0)]
    run = [Event("start", p, "Run", "Running") for p in "ab"]
    fast = [Event("progress", "a", value=2), Event("completed", value=2)]
    assert progress_problems(start + run + fast, RUNNABLE, ["PreRun", "Run"]) == [
        "completedSteps became 2 while part 'b' was still working at step 0:"
        " progress must be the slowest working part's"
    ]
    done_b = [Event("end", "b", "Run", value="ok")]  # b has finished its part
    assert progress_problems(start + run + done_b + fast, RUNNABLE, ["Run"]) == []

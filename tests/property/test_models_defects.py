"""Seeded-defect models in fixtures/: each is caught, and the message names
the defect and where it is (file:line)."""

from __future__ import annotations

from pathlib import Path

import pytest

from malcolm.fsm import ModelError, Problem, check_model, load_model

FIXTURES = Path(__file__).parent / "fixtures"


class GuardsWithoutBeamOn:
    """A guard provider with the runnable guards but not ``beam_on``."""

    def scan_complete(self) -> bool:
        return True

    def is_paused(self) -> bool:
        return False


def _problems(stem: str) -> list[Problem]:
    return check_model(load_model(FIXTURES / f"{stem}.yaml"), GuardsWithoutBeamOn)


def _line_of(stem: str, text: str) -> int:
    lines = (FIXTURES / f"{stem}.yaml").read_text().splitlines()
    return next(i for i, line in enumerate(lines, 1) if text in line)


@pytest.mark.parametrize(
    "stem, anchor, words",
    [
        ("runnable_no_fault", "  Paused:", ["state Paused", "no move to Fault"]),
        ("unreachable_state", "  Calibrating:", ["state Calibrating", "unreachable"]),
        ("unused_phase", "  Calibrate:", ["phase Calibrate", "on no transition"]),
        (
            "busy_cannot_abort",
            "  Calibrating:",
            ["busy state Calibrating", "cannot abort", "Aborting"],
        ),
        (
            "missing_guard",
            "guards: [beam_on]",
            ["guard beam_on", "GuardsWithoutBeamOn"],
        ),
        (
            "call_without_transition",
            "  run: [Ready]",
            ["method run is allowed in Ready", "no run transition leaves Ready"],
        ),
        (
            "phase_fired_by_nothing",
            "phases: [Calibrate]",
            ["transition calibrate Armed->Calibrating", "Calibrate", "nothing fires"],
        ),
    ],
)
def test_design_rule_defect_is_named(stem: str, anchor: str, words: list[str]) -> None:
    problems = _problems(stem)
    assert len(problems) == 1, problems
    (problem,) = problems
    assert problem.file.endswith(f"fixtures/{stem}.yaml")
    assert problem.line == _line_of(stem, anchor)
    text = str(problem)
    assert text.startswith(f"{problem.file}:{problem.line}: ")
    for word in words:
        assert word in text


def test_a_missing_role_is_named() -> None:
    (problem,) = _problems("missing_role")
    assert str(problem) == (
        f"{FIXTURES / 'missing_role.yaml'}: model MissingRole has no state with"
        " role 'fault': every state must be able to move to Fault (rule 2)"
    )


def test_a_shadowed_transition_is_named() -> None:
    """The unguarded done out of PostRun comes first: the guarded one after it
    (and its phase PostRunReady) is never taken, and done's last transition
    is guarded."""
    problems = _problems("shadowed_transition")
    line = _line_of("shadowed_transition", "guards: [scan_complete]")
    first = _line_of("shadowed_transition", "phases: [PostRunArmed]")
    assert [(p.line, p.message) for p in problems] == [
        (
            line,
            "busy state PostRun: the last 'done' transition (done PostRun->Finished)"
            " is guarded, so 'done' may leave PostRun nowhere",
        ),
        (
            line,
            "transition done PostRun->Finished (phases PostRunReady) is never"
            f" taken: the unguarded done PostRun->Armed (line {first}) comes first",
        ),
    ]


def test_undeclared_phase_is_a_load_error() -> None:
    path = FIXTURES / "undeclared_phase.yaml"
    with pytest.raises(ModelError) as info:
        load_model(path)
    error = info.value
    assert error.file == str(path)
    assert error.line == _line_of("undeclared_phase", "phases: [Calibrate]")
    assert "'Calibrate' is not declared" in str(error)
    assert str(error).startswith(f"{path}:{error.line}: ")


def test_extends_cycle_is_a_load_error() -> None:
    with pytest.raises(ModelError) as info:
        load_model(FIXTURES / "cycle_a.yaml")
    (problem,) = info.value.problems
    assert "extends cycle: cycle_a.yaml -> cycle_b.yaml -> cycle_a.yaml" in str(problem)
    assert problem.file.endswith("cycle_b.yaml")
    assert problem.line == _line_of("cycle_b", "extends:")


def test_the_fixtures_only_fail_for_their_seeded_defect() -> None:
    """Without the seeded defect the fixtures would pass: the missing guard is
    the only problem when the provider has it."""

    class AllGuards(GuardsWithoutBeamOn):
        def beam_on(self) -> bool:
            return True

    model = load_model(FIXTURES / "missing_guard.yaml")
    assert check_model(model, AllGuards) == []
    assert check_model(model) == []

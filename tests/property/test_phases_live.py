"""A live controller built for each model (its ``controller:`` class; with
three recorder parts that hook every phase) is taken by a script of calls
through every transition that runs phases (malcolm.conformance.scenarios).
After each call the recorded hook calls must show:

- each move ran exactly its transition's phases, in order, in the source
  state: the reference table's for the builtin models, the model's for
  models given with --malcolm-models;
- every hook of a phase returned before the next phase started and before
  the block moved (a phase runner that returns early is caught), and none
  was cancelled unless a part failed or a call interrupted it;
- during a run, completedSteps never passed a part still doing its steps.
"""

from __future__ import annotations

import functools
from pathlib import Path

import pytest

from malcolm.conformance.phase_table import PhaseRow, load_phase_table
from malcolm.conformance.scenarios import Report, run_script
from malcolm.conformance.testing import controller_or_fail, model_or_fail
from malcolm.fsm import Model, Transition, builtin_models_dir

TABLE = Path(__file__).with_name("phase_table.yaml")


def table_rows(path: Path) -> list[PhaseRow] | None:
    """The table's rows for a builtin model (None for another model)."""
    if path.parent.resolve() != builtin_models_dir().resolve():
        return None
    return load_phase_table(TABLE).get(path.stem)


@functools.cache
def script_report(path: Path) -> tuple[Model, Report]:
    model = model_or_fail(path)
    if controller_or_fail(model) is None:
        pytest.skip(f"{path}: the model names no controller class to build")
    rows = table_rows(path)
    expected = None
    if rows is not None:
        by_key = {r.key: r.phases for r in rows}

        def expected(t: Transition) -> tuple[str, ...]:
            return by_key.get((t.trigger, t.source, t.dest), t.phases)

    return model, run_script(model, expected)


def test_live_controller_runs_the_phases(model_path: Path) -> None:
    model, report = script_report(model_path)
    if report.problems:
        pytest.fail(
            f"{model_path}: a live {model.controller} for model {model.name}:\n"
            + "\n".join(report.problems),
            pytrace=False,
        )


def test_the_script_takes_every_transition_with_phases(model_path: Path) -> None:
    model, report = script_report(model_path)
    if report.problems:
        pytest.skip(
            "the script stopped early (see test_live_controller_runs_the_phases)"
        )
    missed = [
        t
        for t in model.transitions
        if t.phases and (t.trigger, t.source, t.dest) not in report.covered
    ]
    text = "\n".join(
        f"{t.file}:{t.line}: transition {t} ({', '.join(t.phases)})" for t in missed
    )
    if missed and table_rows(model_path) is None:
        pytest.skip(
            "not taken by the script (the controller machines drive them at"
            f" random):\n{text}"
        )
    assert not missed, f"the script never took:\n{text}"

"""Hypothesis state machines drive a LIVE controller built for each model
(the builtin ones, and any given with --malcolm-models): the machine for
its controller class (malcolm.conformance.machines) makes calls and puts
in any state, one at a time or two at once, and injects part failures and
hangs; it checks every move against the model, the phases each move runs
(against the reference table for the builtin models), health, and, for a
runnable device, the scan's steps (interop.md section 1)."""

from __future__ import annotations

import functools
from pathlib import Path

import pytest

from malcolm.conformance.machines import run_machine
from malcolm.conformance.phase_table import load_phase_table
from malcolm.conformance.testing import controller_or_fail, model_or_fail
from malcolm.fsm import Transition, builtin_models_dir

TABLE = Path(__file__).with_name("phase_table.yaml")
#: examples per builtin model (others get DEFAULT_EXAMPLES)
EXAMPLES = {
    "stateful": 30,
    "manager": 30,
    "runnable_device": 60,
    "area_detector_runnable_device": 40,
}
DEFAULT_EXAMPLES = 30


@functools.cache
def _table_phases(stem: str) -> dict[tuple[str, str, str], tuple[str, ...]] | None:
    rows = load_phase_table(TABLE).get(stem)
    return None if rows is None else {r.key: r.phases for r in rows}


def test_controller_machine(model_path: Path) -> None:
    model = model_or_fail(model_path)
    if controller_or_fail(model) is None:
        pytest.skip(f"{model_path}: the model names no controller class to build")
    builtin = model_path.parent.resolve() == builtin_models_dir().resolve()
    table = _table_phases(model_path.stem) if builtin else None
    expected = None
    if table is not None:

        def expected(t: Transition) -> tuple[str, ...]:
            return table.get((t.trigger, t.source, t.dest), t.phases)

    examples = EXAMPLES.get(model_path.stem, DEFAULT_EXAMPLES) if builtin else None
    run_machine(model, examples or DEFAULT_EXAMPLES, expected=expected)

"""The builtin models run the phases the reference table (phase_table.yaml)
says, on each transition, in that order. A model that loses a phase on a
transition, gains one, or runs them in another order (the areaDetector's
plugins must start before its driver) fails here, naming the transition
and the table row."""

from __future__ import annotations

from pathlib import Path

import pytest

from malcolm.conformance.phase_table import load_phase_table, table_problems
from malcolm.fsm import load_model, model_names

TABLE = Path(__file__).with_name("phase_table.yaml")


def test_every_builtin_model_has_a_table() -> None:
    assert sorted(load_phase_table(TABLE)) == model_names()


@pytest.mark.parametrize("stem", model_names())
def test_model_runs_the_phases_of_the_table(stem: str) -> None:
    rows = load_phase_table(TABLE).get(stem, [])
    problems = table_problems(load_model(stem), rows)
    assert problems == [], "\n".join(str(p) for p in problems)

"""Every model (builtin, or given with --malcolm-models) follows the design
rules (malcolm.fsm.check_model, docs/fsm.md "Design rules")."""

from __future__ import annotations

from pathlib import Path

import pytest

from malcolm.conformance.testing import controller_or_fail, model_or_fail
from malcolm.fsm import check_model


def test_model_follows_design_rules(model_path: Path) -> None:
    model = model_or_fail(model_path)
    controller = controller_or_fail(model)
    problems = check_model(model, guard_provider=controller)
    if problems:
        pytest.fail("\n".join(str(p) for p in problems), pytrace=False)


def test_every_state_has_an_entry_in_moves(model_path: Path) -> None:
    model = model_or_fail(model_path)
    assert set(model.moves()) == set(model.states)
    assert model.initial in model.states

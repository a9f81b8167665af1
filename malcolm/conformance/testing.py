"""Helpers the conformance tests share: a model, or a clean test failure."""

from __future__ import annotations

from functools import cache
from pathlib import Path

import pytest

from malcolm.fsm import Model, ModelError, load_model, resolve_controller


@cache
def _load(path: Path) -> Model | ModelError:
    try:
        return load_model(path)
    except ModelError as e:
        return e


def model_or_fail(path: Path) -> Model:
    """The model at ``path``; a file that does not load fails the test with
    its problems (``file:line: message``), not a traceback."""
    found = _load(path)
    if isinstance(found, ModelError):
        pytest.fail(str(found), pytrace=False)
    return found


def controller_or_fail(model: Model) -> type | None:
    """The model's controller class (None if it names none); a class that
    cannot be imported fails the test with where the model names it."""
    try:
        return resolve_controller(model)
    except ModelError as e:
        pytest.fail(str(e), pytrace=False)

"""Roles and tags in models: what controllers read instead of state names."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from malcolm.fsm import ModelError, load_model


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / f"{name}.yaml"
    path.write_text(textwrap.dedent(text))
    return path


def test_builtin_roles_and_tags() -> None:
    model = load_model("runnable_device")
    assert model.state_for("running") == "Running"
    assert model.state_for("fault") == "Fault"
    assert model.is_state("Armed", "armed")
    assert not model.is_state("Armed", "running")
    assert model.states_tagged("quiet") == {
        "Disabled",
        "Disabling",
        "Fault",
        "Resetting",
        "Loading",
    }
    with pytest.raises(KeyError, match="no state with role 'nope'"):
        model.state_for("nope")


def test_phase_roles_tags_and_descriptions(tmp_path: Path) -> None:
    path = write(
        tmp_path,
        "m",
        """\
        name: M
        initial: A
        states:
          A: {role: idle}
          B: {busy: true, role: working, tags: [quiet, long_one]}
        phases:
          Work: {description: the work, role: work, tags: [long]}
          Tidy: tidy up
        transitions:
          - {trigger: go, source: A, dest: B}
          - {trigger: done, source: B, dest: A, phases: [Work, Tidy]}
        """,
    )
    model = load_model(path)
    assert model.phases == {"Work": "the work", "Tidy": "tidy up"}
    assert model.phase_for("work") == "Work"
    assert model.phase_for("tidy") is None
    assert model.phases_tagged("long") == {"Work"}
    assert model.states["B"].tags == frozenset({"quiet", "long_one"})


def test_child_keeps_roles_it_does_not_restate(tmp_path: Path) -> None:
    write(
        tmp_path,
        "base",
        """\
        name: Base
        initial: A
        states:
          A: {role: idle, tags: [quiet]}
        phases:
          Work: {description: w, role: work}
        transitions:
          - {trigger: done, source: A, dest: A, phases: [Work]}
        """,
    )
    child = write(
        tmp_path,
        "child",
        """\
        name: Child
        extends: base
        states:
          A: {description: still idle}
        phases:
          Work: more words
        """,
    )
    model = load_model(child)
    assert model.state_for("idle") == "A"
    assert model.states_tagged("quiet") == {"A"}
    assert model.phase_for("work") == "Work"
    assert model.phases["Work"] == "more words"


def test_duplicate_and_bad_roles_are_problems(tmp_path: Path) -> None:
    path = write(
        tmp_path,
        "bad",
        """\
        name: Bad
        initial: A
        states:
          A: {role: idle}
          B: {role: idle}
          C: {role: Not-A-Role}
        transitions:
          - {trigger: go, source: A, dest: B}
          - {trigger: go, source: B, dest: C}
        """,
    )
    with pytest.raises(ModelError) as info:
        load_model(path)
    text = str(info.value)
    assert "bad.yaml:5: state B: role 'idle' is already the role of state A" in text
    assert "bad.yaml:6: state C: role must be a lower_snake_case name" in text

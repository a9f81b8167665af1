"""extends merges models; replace_phases splits an inherited phase."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from malcolm.fsm import ModelError, load_model

BASE = """\
name: Base
controller: some.module:BaseController
initial: Idle
states:
  Idle: {busy: false, description: idle}
  Working: {busy: true}
phases:
  Work: the work
  Tidy: tidy up
transitions:
  - {trigger: start, source: Idle, dest: Working}
  - {trigger: done, source: Working, dest: Idle, phases: [Work, Tidy]}
methods:
  start: [Idle]
attributes:
  speed: {allowed: [Idle], trigger: start}
"""


def write(tmp_path: Path, text: str, name: str) -> Path:
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


@pytest.fixture
def base(tmp_path: Path) -> Path:
    return write(tmp_path, BASE, "base.yaml")


def test_child_adds_and_redefines(tmp_path: Path, base: Path) -> None:
    child = write(
        tmp_path,
        """\
        name: Child
        extends: base
        states:
          Idle: {description: waiting}
          Paused: {busy: false}
        phases:
          Pause: stop for a while
        transitions:
          - {trigger: pause, source: Working, dest: Paused, phases: [Pause]}
          - {trigger: start, source: Paused, dest: Working}
        methods:
          start: [Paused]
          pause: [Working]
        attributes:
          speed: {allowed: [Paused]}
        """,
        "child.yaml",
    )
    model = load_model(child)
    assert model.name == "Child"
    assert model.parent is not None and model.parent.name == "Base"
    assert model.initial == "Idle"
    assert model.controller == "some.module:BaseController"
    assert list(model.states) == ["Idle", "Working", "Paused"]
    idle = model.states["Idle"]
    assert (idle.busy, idle.description) == (False, "waiting")
    assert (idle.file, idle.line) == (str(child), 4)
    assert model.states["Working"].file == str(base)
    assert list(model.phases) == ["Work", "Tidy", "Pause"]
    assert [str(t) for t in model.transitions] == [
        "start Idle->Working",
        "done Working->Idle",
        "pause Working->Paused",
        "start Paused->Working",
    ]
    assert [t.file for t in model.transitions] == [str(base)] * 2 + [str(child)] * 2
    assert model.methods == {
        "start": frozenset({"Idle", "Paused"}),
        "pause": frozenset({"Working"}),
    }
    assert model.attributes["speed"].allowed == frozenset({"Idle", "Paused"})
    assert model.attributes["speed"].trigger == "start"


def test_child_may_override_initial_and_controller(tmp_path: Path, base: Path) -> None:
    child = write(
        tmp_path,
        "name: Child\nextends: base\ninitial: Working\ncontroller: a.b:C\n",
        "child.yaml",
    )
    model = load_model(child)
    assert (model.initial, model.controller) == ("Working", "a.b:C")


def test_replace_phases(tmp_path: Path, base: Path) -> None:
    child = write(
        tmp_path,
        """\
        name: Child
        extends: base
        phases:
          WorkStart: start working
          WorkWait: wait for the work
        replace_phases:
          Work: [WorkStart, WorkWait]
        """,
        "child.yaml",
    )
    model = load_model(child)
    assert list(model.phases) == ["Tidy", "WorkStart", "WorkWait"]
    (done,) = model.transitions_for("done", "Working")
    assert done.phases == ("WorkStart", "WorkWait", "Tidy")
    # the parent is untouched
    assert model.parent is not None
    assert model.parent.transitions_for("done", "Working")[0].phases == ("Work", "Tidy")


def test_replaced_phase_cannot_be_used_again(tmp_path: Path, base: Path) -> None:
    child = write(
        tmp_path,
        """\
        name: Child
        extends: base
        replace_phases:
          Work: [Tidy]
        transitions:
          - {trigger: start, source: Working, dest: Working, phases: [Work]}
        """,
        "child.yaml",
    )
    with pytest.raises(ModelError, match="child.yaml:6: .*'Work' is not declared"):
        load_model(child)


@pytest.mark.parametrize(
    "text, message",
    [
        (
            "replace_phases:\n  Play: [Tidy]\n",
            "4: replace_phases: 'Play' is not a phase",
        ),
        ("replace_phases:\n  Work: [Rest]\n", "4: replace_phases Work: phase 'Rest'"),
    ],
)
def test_replace_phases_errors(
    tmp_path: Path, base: Path, text: str, message: str
) -> None:
    child = write(tmp_path, "name: Child\nextends: base\n" + text, "child.yaml")
    with pytest.raises(ModelError, match=message):
        load_model(child)


def test_replace_phases_needs_extends(tmp_path: Path) -> None:
    path = write(tmp_path, BASE + "replace_phases:\n  Work: [Tidy]\n", "m.yaml")
    with pytest.raises(ModelError, match="m.yaml:17: replace_phases needs extends"):
        load_model(path)


def test_parent_next_to_child_wins_over_builtin(tmp_path: Path) -> None:
    write(tmp_path, BASE.replace("name: Base", "name: Stateful"), "stateful.yaml")
    child = write(tmp_path, "name: Child\nextends: stateful\n", "child.yaml")
    assert load_model(child).parent.path == tmp_path / "stateful.yaml"


def test_builtin_parent_when_not_next_to_child(tmp_path: Path) -> None:
    child = write(tmp_path, "name: Child\nextends: runnable_device\n", "child.yaml")
    model = load_model(child)
    assert model.moves() == load_model("runnable_device").moves()


def test_builtin_chain() -> None:
    names = []
    model = load_model("area_detector_runnable_device")
    while model is not None:
        names.append(model.name)
        model = model.parent
    assert names == [
        "AreaDetectorRunnableDevice",
        "RunnableDevice",
        "Manager",
        "Stateful",
    ]


def test_area_detector_splits_run() -> None:
    model = load_model("area_detector_runnable_device")
    assert "Run" not in model.phases
    (done,) = model.transitions_for("done", "Running")
    assert done.phases == (
        "PreRun",
        "PreRunPluginStart",
        "PreRunDriverStart",
        "Running",
        "PostRun",
    )
    assert set(model.phases) == set(load_model("runnable_device").phases) - {"Run"} | {
        "PreRunPluginStart",
        "PreRunDriverStart",
        "Running",
        "PostRun",
    }

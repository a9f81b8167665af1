"""Loading models: every problem is reported with file:line."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from malcolm.fsm import ModelError, Problem, builtin_models_dir, load_model, model_names

MINIMAL = """\
name: Tiny
initial: Idle
states:
  Idle: {busy: false}
  Working: {busy: true, description: doing it}
phases:
  Work: the work
transitions:
  - {trigger: start, source: Idle, dest: Working}
  - {trigger: done, source: Working, dest: Idle, phases: [Work]}
methods:
  start: [Idle]
attributes:
  speed: {allowed: [Idle]}
"""


def write(tmp_path: Path, text: str, name: str = "model.yaml") -> Path:
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def errors(path: Path) -> list[Problem]:
    with pytest.raises(ModelError) as info:
        load_model(path)
    return info.value.problems


def test_minimal_model_loads(tmp_path: Path) -> None:
    model = load_model(write(tmp_path, MINIMAL))
    assert model.name == "Tiny"
    assert model.initial == "Idle"
    assert model.controller is None
    assert model.states["Working"].busy
    assert model.states["Working"].description == "doing it"
    assert model.states["Working"].line == 5
    assert model.phases == {"Work": "the work"}
    assert [str(t) for t in model.transitions] == [
        "start Idle->Working",
        "done Working->Idle",
    ]
    assert model.transitions[1].phases == ("Work",)
    assert model.transitions[1].line == 10
    assert model.methods == {"start": frozenset({"Idle"})}
    assert model.attributes["speed"].allowed == frozenset({"Idle"})
    assert model.attributes["speed"].trigger is None


def test_builtin_models_are_found_by_name() -> None:
    assert model_names() == [
        "area_detector_runnable_device",
        "manager",
        "runnable_device",
        "stateful",
    ]
    model = load_model("stateful")
    assert model.path == builtin_models_dir() / "stateful.yaml"
    assert model.controller == "malcolm.controllers.stateful:StatefulController"


def test_search_directories_come_before_builtins(tmp_path: Path) -> None:
    write(tmp_path, MINIMAL.replace("Tiny", "Stateful"), "stateful.yaml")
    assert load_model("stateful", search=[tmp_path]).path == tmp_path / "stateful.yaml"


def test_unknown_name_and_missing_file(tmp_path: Path) -> None:
    with pytest.raises(ModelError, match="nosuch.yaml: not found in"):
        load_model("nosuch")
    with pytest.raises(ModelError, match="no such model file"):
        load_model(tmp_path / "gone.yaml")


def test_bad_yaml_names_file_and_line(tmp_path: Path) -> None:
    path = write(tmp_path, "name: Bad\nstates:\n  Idle: {busy: true\n  Other: x\n")
    (problem,) = errors(path)
    assert problem.file == str(path)
    assert problem.line == 4
    assert problem.message.startswith("YAML error")
    assert str(problem).startswith(f"{path}:4: YAML error")


def test_top_level_must_be_a_mapping(tmp_path: Path) -> None:
    (problem,) = errors(write(tmp_path, "- a\n- b\n"))
    assert "must be a mapping" in problem.message


def test_all_problems_are_reported_at_once(tmp_path: Path) -> None:
    text = MINIMAL.replace("initial: Idle", "initial: Nowhere")
    text = text.replace("  Idle: {busy: false}", "  Idle: {busy: false, colour: red}")
    text = text.replace("dest: Working}", "dest: Workin}")
    text = text.replace("phases: [Work]}", "phases: [Play]}")
    text = text.replace("start: [Idle]", "start: [Idle, Asleep]")
    text = text.replace(
        "speed: {allowed: [Idle]}", "speed: {allowed: [Busy], when: now}"
    )
    text += "colour: blue\n"
    path = write(tmp_path, text)
    with pytest.raises(ModelError) as info:
        load_model(path)
    error = info.value
    found = {(p.line, p.message) for p in error.problems}
    assert found == {
        (
            15,
            "unknown key 'colour' in model (expected one of name, description, "
            "extends, controller, initial, states, phases, replace_phases, "
            "transitions, methods, attributes)",
        ),
        (
            4,
            "unknown key 'colour' in state Idle"
            " (expected one of busy, description, role, tags)",
        ),
        (2, "initial 'Nowhere' is not a state"),
        (9, "transition start dest: 'Workin' is not a state"),
        (10, "transition done: phase 'Play' is not declared under phases"),
        (12, "method start: 'Asleep' is not a state"),
        (
            14,
            "unknown key 'when' in attribute speed (expected one of allowed, trigger)",
        ),
        (14, "attribute speed: 'Busy' is not a state"),
    }
    assert error.file == str(path)
    assert error.line == error.problems[0].line
    assert str(error).splitlines() == [str(p) for p in error.problems]
    assert all(line.startswith(f"{path}:") for line in str(error).splitlines())


def test_unknown_transition_key_and_missing_source(tmp_path: Path) -> None:
    text = MINIMAL.replace(
        "- {trigger: start, source: Idle, dest: Working}",
        "- {trigger: start, dest: Working, when: later}",
    )
    problems = errors(write(tmp_path, text))
    assert [(p.line, p.message) for p in problems] == [
        (
            9,
            "unknown key 'when' in transition (expected one of trigger, source, "
            "dest, guards, unless, phases)",
        ),
        (9, "transition start: source is missing"),
    ]


def test_source_list_items_report_their_own_line(tmp_path: Path) -> None:
    text = MINIMAL.replace(
        "  - {trigger: start, source: Idle, dest: Working}",
        "  - trigger: start\n    source:\n      - Idle\n      - Sleeping\n"
        "    dest: Working",
    )
    (problem,) = errors(write(tmp_path, text))
    assert (problem.line, problem.message) == (
        12,
        "transition start source: 'Sleeping' is not a state",
    )


def test_duplicate_state_in_one_file(tmp_path: Path) -> None:
    text = MINIMAL.replace(
        "  Idle: {busy: false}\n", "  Idle: {busy: false}\n  Idle: {}\n"
    )
    (problem,) = errors(write(tmp_path, text))
    assert problem.line == 5
    assert "duplicate key 'Idle'" in problem.message


@pytest.mark.parametrize(
    "old, new, message",
    [
        ("name: Tiny", "name: tiny", "name must be a CamelCase identifier"),
        ("initial: Idle\n", "", "initial is required"),
        ("{busy: true, description", "{busy: yes please, description", "busy must"),
        ("trigger: start,", "trigger: 'st art',", "trigger must be a name"),
        ("source: Idle,", "source: {a: b},", "source must be a name or a list"),
        (
            "initial: Idle\n",
            "initial: Idle\ncontroller: not a dotted path\n",
            "must look like 'package.module:Class'",
        ),
    ],
)
def test_malformed_values(tmp_path: Path, old: str, new: str, message: str) -> None:
    problems = errors(write(tmp_path, MINIMAL.replace(old, new)))
    assert any(message in p.message for p in problems), problems


def test_missing_parent(tmp_path: Path) -> None:
    path = write(tmp_path, "name: Child\nextends: no_such_parent\n")
    (problem,) = errors(path)
    assert (problem.file, problem.line) == (str(path), 2)
    assert "extends 'no_such_parent': no no_such_parent.yaml" in problem.message


def test_extends_cycle_names_the_files(tmp_path: Path) -> None:
    write(tmp_path, "name: A\nextends: b\n", "a.yaml")
    write(tmp_path, "name: B\nextends: c\n", "b.yaml")
    write(tmp_path, "name: C\nextends: a\n", "c.yaml")
    (problem,) = errors(tmp_path / "a.yaml")
    assert problem.file == str(tmp_path / "c.yaml")
    assert problem.line == 2
    assert problem.message == "extends cycle: a.yaml -> b.yaml -> c.yaml -> a.yaml"


def test_self_extension_is_a_cycle(tmp_path: Path) -> None:
    (problem,) = errors(write(tmp_path, "name: A\nextends: a\n", "a.yaml"))
    assert problem.message == "extends cycle: a.yaml -> a.yaml"


def test_problems_in_a_parent_name_the_parent(tmp_path: Path) -> None:
    write(tmp_path, MINIMAL.replace("initial: Idle", "initial: Nowhere"), "base.yaml")
    (problem,) = errors(write(tmp_path, "name: Child\nextends: base\n"))
    assert problem.file == str(tmp_path / "base.yaml")
    assert problem.line == 2


def test_characters_yaml_forbids_and_non_utf8_are_problems_not_crashes(tmp_path):
    from malcolm.fsm import ModelError, load_model

    bad = tmp_path / "bad.yaml"
    bad.write_bytes(b"name: X\x1f\n")
    with pytest.raises(ModelError, match="YAML error"):
        load_model(bad)
    bad.write_bytes(b"\xff\xfename: X\n")
    with pytest.raises(ModelError, match="not UTF-8"):
        load_model(bad)

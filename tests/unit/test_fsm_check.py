"""check_model's design rules and resolve_controller, on small models."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from malcolm.fsm import ModelError, check_model, load_model, resolve_controller

GOOD = """\
name: Small
initial: Disabled
states:
  Disabled: {}
  Ready: {}
  Busy: {busy: true}
  Fault: {}
  Disabling: {busy: true}
phases:
  Work: work
  Disable: let go
transitions:
  - {trigger: enable, source: Disabled, dest: Ready}
  - {trigger: go, source: Ready, dest: Busy}
  - {trigger: done, source: Busy, dest: Ready, guards: [ok], phases: [Work]}
  - {trigger: done, source: Busy, dest: Fault}
  - {trigger: fault, source: [Ready, Busy, Disabling], dest: Fault}
  - {trigger: disable, source: [Ready, Busy, Fault], dest: Disabling}
  - {trigger: done, source: Disabling, dest: Disabled, phases: [Disable]}
methods:
  go: [Ready]
  hello: [Ready, Busy]
attributes:
  target: {allowed: [Ready], trigger: go}
"""


def model_from(tmp_path: Path, text: str):
    path = tmp_path / "small.yaml"
    path.write_text(textwrap.dedent(text))
    return load_model(path)


def at(tmp_path: Path, line: int) -> str:
    return f"{tmp_path}/small.yaml:{line}: "


def messages(tmp_path: Path, text: str, provider: type | None = None) -> list[str]:
    return [str(p) for p in check_model(model_from(tmp_path, text), provider)]


def test_good_model_has_no_problems(tmp_path: Path) -> None:
    assert messages(tmp_path, GOOD) == []


def test_fault_and_disabling_needed_from_every_state(tmp_path: Path) -> None:
    text = GOOD.replace(
        "source: [Ready, Busy, Disabling], dest: Fault",
        "source: [Ready, Busy], dest: Fault",
    )
    assert messages(tmp_path, text) == [
        at(tmp_path, 8) + "state Disabling has no move to Fault"
    ]


def test_unreachable(tmp_path: Path) -> None:
    text = GOOD.replace("  - {trigger: enable, source: Disabled, dest: Ready}\n", "")
    found = messages(tmp_path, text)
    assert (
        at(tmp_path, 5) + "state Ready is unreachable from initial state Disabled"
        in found
    )
    assert any("state Busy is unreachable" in m for m in found)


def test_busy_state_without_abort_move_to_disabling(tmp_path: Path) -> None:
    text = GOOD.replace(
        "source: [Ready, Busy, Fault], dest: Disabling",
        "source: [Ready, Fault], dest: Disabling",
    )
    found = messages(tmp_path, text)
    assert (
        at(tmp_path, 6) + "busy state Busy cannot abort: no move to Disabling" in found
    )


def test_busy_state_must_be_left_by_unguarded_done(tmp_path: Path) -> None:
    text = GOOD.replace("  - {trigger: done, source: Busy, dest: Fault}\n", "")
    found = messages(tmp_path, text)
    assert found == [
        at(tmp_path, 15) + "busy state Busy: the last 'done' transition "
        "(done Busy->Ready) is guarded, so 'done' may leave Busy nowhere"
    ]
    guarded = "  - {trigger: done, source: Busy, dest: Ready, guards: [ok], "
    text = text.replace(guarded + "phases: [Work]}\n", "")
    text = text.replace("  Work: work\n", "")
    assert messages(tmp_path, text) == [
        at(tmp_path, 6) + "busy state Busy has no 'done' transition"
    ]


def test_unused_phase(tmp_path: Path) -> None:
    text = GOOD.replace("  Disable: let go\n", "  Disable: let go\n  Nap: never\n")
    assert messages(tmp_path, text) == [
        at(tmp_path, 12) + "phase Nap is on no transition"
    ]


def test_method_named_like_a_trigger_needs_its_transitions(tmp_path: Path) -> None:
    text = GOOD.replace("  go: [Ready]", "  go: [Ready, Fault]")
    assert messages(tmp_path, text) == [
        at(tmp_path, 21)
        + "method go is allowed in Fault but no go transition leaves Fault"
    ]


def test_attribute_trigger_needs_its_transitions(tmp_path: Path) -> None:
    text = GOOD.replace(
        "{allowed: [Ready], trigger: go}", "{allowed: [Ready, Fault], trigger: go}"
    )
    assert messages(tmp_path, text) == [
        at(tmp_path, 24)
        + "attribute target may be put in Fault but no go transition leaves Fault"
    ]
    text = GOOD.replace("trigger: go}", "trigger: went}")
    assert messages(tmp_path, text) == [
        at(tmp_path, 24) + "attribute target: trigger went is on no transition"
    ]


def test_guards_checked_only_with_a_provider(tmp_path: Path) -> None:
    class Without:
        ok = True  # not callable

    class With:
        def ok(self) -> bool:
            return True

    assert messages(tmp_path, GOOD) == []
    assert messages(tmp_path, GOOD, With) == []
    assert messages(tmp_path, GOOD, Without) == [
        at(tmp_path, 15)
        + "guard ok on transition done Busy->Ready is not provided by Without"
    ]


def test_unless_guards_are_checked_too(tmp_path: Path) -> None:
    text = GOOD.replace("guards: [ok]", "unless: [stuck]")
    assert messages(tmp_path, text, object) == [
        at(tmp_path, 15)
        + "guard stuck on transition done Busy->Ready is not provided by object"
    ]


def test_problems_point_at_inherited_files(tmp_path: Path) -> None:
    (tmp_path / "child.yaml").write_text(
        "name: Child\nextends: runnable_device\nphases:\n  Nap: zzz\n"
    )
    model = load_model(tmp_path / "child.yaml")
    (problem,) = check_model(model)
    assert (problem.file, problem.line) == (str(tmp_path / "child.yaml"), 4)


def test_resolve_controller(tmp_path: Path) -> None:
    assert resolve_controller(model_from(tmp_path, GOOD)) is None
    found = model_from(tmp_path, GOOD + "controller: collections:OrderedDict\n")
    import collections

    assert resolve_controller(found) is collections.OrderedDict
    missing = model_from(tmp_path, GOOD + "controller: malcolm.no_such_module:Thing\n")
    assert resolve_controller(missing) is None
    no_class = model_from(tmp_path, GOOD + "controller: collections:NoSuchThing\n")
    with pytest.raises(
        ModelError, match=r"small.yaml:25: collections has no class NoSuchThing"
    ):
        resolve_controller(no_class)


def test_resolve_controller_reports_broken_imports(tmp_path: Path, monkeypatch) -> None:
    (tmp_path / "broken_controller_mod.py").write_text(
        "import no_such_dependency_xyz\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    model = model_from(tmp_path, GOOD + "controller: broken_controller_mod:C\n")
    with pytest.raises(
        ModelError, match="small.yaml:25: cannot import broken_controller_mod"
    ):
        resolve_controller(model)

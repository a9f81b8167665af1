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
  Disabled: {role: disabled}
  Ready: {}
  Busy: {busy: true}
  Fault: {role: fault}
  Disabling: {busy: true, role: disabling}
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


# ---- roles, not names


def test_rules_read_roles_not_state_names(tmp_path: Path) -> None:
    text = (
        GOOD.replace("Disabled", "Asleep")
        .replace("Disabling", "LettingGo")
        .replace("Fault", "Broken")
    )
    assert messages(tmp_path, text) == []
    broken = text.replace(
        "source: [Ready, Busy, LettingGo], dest: Broken",
        "source: [Ready, Busy], dest: Broken",
    )
    assert messages(tmp_path, broken) == [
        at(tmp_path, 8) + "state LettingGo has no move to Broken"
    ]


def test_a_role_a_rule_needs_is_named_when_missing(tmp_path: Path) -> None:
    text = GOOD.replace("Fault: {role: fault}", "Fault: {}")
    assert messages(tmp_path, text) == [
        f"{tmp_path}/small.yaml: model Small has no state with role 'fault': "
        "every state must be able to move to Fault (rule 2)"
    ]


# ---- transitions that are never taken


def test_a_transition_after_an_unguarded_one_is_never_taken(tmp_path: Path) -> None:
    text = GOOD.replace("guards: [ok], ", "")
    assert messages(tmp_path, text) == [
        at(tmp_path, 16) + "transition done Busy->Fault is never taken: the "
        "unguarded done Busy->Ready (line 15) comes first"
    ]


NAP = "  - {trigger: nap, source: Ready, dest: Busy, phases: [Work]}\n"


def with_nap(extra_method: str = "") -> str:
    text = GOOD.replace("transitions:\n", "transitions:\n" + NAP)
    if extra_method:
        text = text.replace("methods:\n", f"methods:\n  {extra_method}\n")
    return text


def test_phases_on_a_transition_nothing_fires(tmp_path: Path) -> None:
    (found,) = messages(tmp_path, with_nap())
    assert found.startswith(
        at(tmp_path, 13) + "transition nap Ready->Busy runs phases Work but "
        "nothing fires it: 'nap' is not a trigger the controller fires; "
        "no method nap is listed under methods"
    )


def test_a_call_fires_only_where_it_is_allowed(tmp_path: Path) -> None:
    found = messages(tmp_path, with_nap("nap: [Busy]"))
    assert (
        at(tmp_path, 13)
        + (
            "transition nap Ready->Busy runs phases Work but nothing fires it: "
            "'nap' is not a trigger the controller fires; method nap is not "
            "allowed in Ready; no attribute put fires nap in Ready"
        )
        in found
    )
    assert messages(tmp_path, with_nap("nap: [Ready]")) == []


def test_a_controller_must_implement_the_call(tmp_path: Path) -> None:
    class Controller:  # looks like a controller: it exposes calls
        def add_call(self, name: str) -> None: ...

        def ok(self) -> bool:
            return True

    class Napper(Controller):
        def do_nap(self) -> None: ...

    class FiresNap(Controller):
        fires = ("nap",)

    text = with_nap("nap: [Ready]")
    (found,) = messages(tmp_path, text, Controller)
    assert "Controller does not implement nap() (do_nap)" in found
    assert messages(tmp_path, text, Napper) == []
    assert messages(tmp_path, with_nap(), FiresNap) == []


def test_an_attribute_put_fires_its_trigger(tmp_path: Path) -> None:
    text = with_nap().replace("trigger: go}", "trigger: nap}")
    text = text.replace("  - {trigger: go, source: Ready, dest: Busy}\n", "")
    text = text.replace("  go: [Ready]\n", "")
    assert messages(tmp_path, text) == []

"""The phase reference table: reading it, comparing a model with it, and
printing one from models (malcolm.conformance.phase_table)."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from malcolm.conformance.phase_table import (
    dump_phase_table,
    load_phase_table,
    main,
    table_problems,
)
from malcolm.fsm import ModelError, load_model

STATEFUL = """\
stateful:
  - {trigger: init, source: Disabled, dest: Resetting, phases: [Init]}
  - {trigger: reset, source: [Fault, Disabled], dest: Resetting, phases: []}
  - {trigger: done, source: Resetting, dest: Ready, phases: [Reset]}
  - {trigger: fault, source: [Resetting, Ready, Disabling], dest: Fault, phases: []}
  - {trigger: disable, source: [Resetting, Ready, Fault], dest: Disabling, phases: []}
  - {trigger: done, source: Disabling, dest: Disabled, phases: [Disable]}
"""


def table(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "table.yaml"
    path.write_text(textwrap.dedent(text))
    return path


def messages(tmp_path: Path, text: str, stem: str = "stateful") -> list[str]:
    rows = load_phase_table(table(tmp_path, text))[stem]
    return [str(p) for p in table_problems(load_model(stem), rows)]


def test_a_matching_table_has_no_problems(tmp_path: Path) -> None:
    assert messages(tmp_path, STATEFUL) == []


def test_other_phases_name_the_transition_and_the_row(tmp_path: Path) -> None:
    text = STATEFUL.replace("phases: [Reset]", "phases: [Reset, Init]")
    path = tmp_path / "table.yaml"
    (found,) = messages(tmp_path, text)
    model = load_model("stateful")
    done = model.transitions_for("done", "Resetting")[0]
    assert found == (
        f"{done.file}:{done.line}: transition done Resetting->Ready runs phases"
        f" [Reset], but the phase table ({path}:4) says [Reset, Init]"
    )


def test_a_missing_row_and_an_extra_row(tmp_path: Path) -> None:
    text = STATEFUL.replace(
        "  - {trigger: done, source: Resetting, dest: Ready, phases: [Reset]}\n",
        "  - {trigger: done, source: Resetting, dest: Fault, phases: [Reset]}\n",
    )
    found = messages(tmp_path, text)
    assert any(
        m.endswith("transition done Resetting->Ready (phases [Reset]) is not in the"
                   " phase table for Stateful") for m in found
    )  # fmt: skip
    assert any(
        m.startswith(f"{tmp_path}/table.yaml:4: stateful: the phase table has"
                     " transition done Resetting->Fault (phases [Reset]), which"
                     " model Stateful") for m in found
    )  # fmt: skip


def test_a_replaced_phase_names_the_model_that_replaced_it(tmp_path: Path) -> None:
    model = load_model("area_detector_runnable_device")
    text = dump_phase_table({"ad": model}).replace(
        "PreRunPluginStart, PreRunDriverStart", "PreRunDriverStart, PreRunPluginStart"
    )
    rows = load_phase_table(table(tmp_path, text))["ad"]
    (found,) = [str(p) for p in table_problems(model, rows)]
    assert "transition done Running->PostRun runs phases [PreRun," in found
    assert (
        "(phases declared by AreaDetectorRunnableDevice: PreRunPluginStart at" in found
    )
    assert "area_detector_runnable_device.yaml:" in found


@pytest.mark.parametrize(
    "row, message",
    [
        ("- {trigger: x, source: A}", "no 'dest', no 'phases'"),
        ("- {trigger: x, source: A, dest: B, phases: [P], when: now}", "unknown key"),
        ("- {trigger: x, source: [], dest: B, phases: []}", "source a name or a list"),
        ("- [x, A, B]", "a row is a mapping"),
    ],
)
def test_bad_rows_are_named_at_their_line(
    tmp_path: Path, row: str, message: str
) -> None:
    path = table(tmp_path, f"# a table\nm:\n  {row}\n")
    with pytest.raises(ModelError) as info:
        load_phase_table(path)
    (problem,) = info.value.problems
    assert (problem.file, problem.line) == (str(path), 3)
    assert message in problem.message


def test_the_printed_table_of_the_builtin_models_matches_them(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    stems = ["stateful", "manager", "runnable_device", "area_detector_runnable_device"]
    assert main(stems) == 0
    path = table(tmp_path, capsys.readouterr().out)
    loaded = load_phase_table(path)
    assert sorted(loaded) == sorted(stems)
    for stem in stems:
        assert table_problems(load_model(stem), loaded[stem]) == []
    assert main([]) == 2
    assert main(["no_such_model"]) == 1

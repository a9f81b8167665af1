"""`malcolm check`: every kind of file, every problem as file:line: message."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from malcolm.checker import Finding, check_file, checks, detect_kind
from malcolm.cli import main

ROOT = Path(__file__).resolve().parents[2]
FIXTURES = Path(__file__).parent / "config_fixtures"
MODELS = ROOT / "models"
MODEL_DEFECTS = ROOT / "tests/property/fixtures"
PROBLEM_LINE = re.compile(r"^.+:\d+: .+$|^.+: .+$")


def run(capsys, *argv):
    status = main(["check", *map(str, argv)])
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err
    for line in out.splitlines():
        assert PROBLEM_LINE.match(line), line
    return status, out.splitlines(), err


def write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


# ---- telling kinds apart


@pytest.mark.parametrize(
    ("text", "kind"),
    [
        ("name: X\nstates:\n  A: {}\n", "model"),
        ("transitions: []\n", "model"),
        ("extends: stateful\nmethods: {}\n", "model"),
        ("include: common.yaml\n", "process"),
        ("define.String:\n    name: a\n    value: b\n", "process"),
        ("block.demo.Hello:\n    mri: X:HELLO\n", "process"),
        ("block.demo.Hello: {mri: X}\n", "process"),
        # nothing but block.* sections: serve reads it as a process file
        ("block.ADCore.PositionPlugin:\n    name: pos\n", "process"),
        (
            "init.String:\n  name: p\nblock.ADCore.PositionPlugin:\n  name: c\n",
            "definition",
        ),
        ("controller.X:\nblock.ADCore.PositionPlugin:\n    name: pos\n", "definition"),
        ("parts.PalettePart:\n    name: PCAP\n", "design"),
        ("fixed.Int:\n    name: A.B\n    value: 1\n", "design"),
        ("parts.ModelPart:\n    name: M\n", "design"),
        ("init.String:\n    name: prefix\n", "definition"),
        ("", "definition"),
        ("this is: [not yaml\n", "definition"),
    ],
)
def test_detect_kind(text, kind):
    assert detect_kind(text) == kind


def test_the_repository_files_are_told_apart():
    assert check_file(MODELS / "stateful.yaml").kind == "model"
    assert check_file(MODELS / "area_detector_runnable_device.yaml").kind == "model"
    assert check_file(FIXTURES / "process/beamline.yaml").kind == "process"
    assert check_file(FIXTURES / "process/common.yaml").kind == "process"
    assert check_file(FIXTURES / "designs/PositionBased.yaml").kind == "design"
    assert check_file(FIXTURES / "blocks/demo/Broken.yaml").kind == "definition"


# ---- definitions


def test_broken_definition_reports_every_problem(capsys):
    broken = FIXTURES / "blocks/demo/Broken.yaml"
    status, out, err = run(capsys, broken)
    assert status == 1
    assert out == [
        f"{broken}:3: default 'lots' is not an Int",
        f"{broken}:7: unknown parameter '{{prefx}}' in 'pv'",
        f"{broken}:9: unknown section type 'gui.Grop' (did you mean 'gui.Group'?)",
    ]
    assert "3 problems in 1 of 1 file" in err


def test_a_good_definition_is_ok(capsys, tmp_path):
    write(tmp_path / "blocks/t/Other.yaml", "init.String:\n    name: prefix\n")
    good = write(
        tmp_path / "blocks/t/Good.yaml",
        "init.String:\n    name: prefix\n    required: true\n"
        "gui.Group:\n    name: g\n"
        "client.t.Other:\n    name: other\n    fullname: '{prefix}:OTHER'\n",
    )
    status, out, err = run(capsys, good)
    assert (status, out) == (0, [])
    assert "1 file OK" in err


def test_unknown_section_kinds_are_reported(capsys, tmp_path):
    bad = write(
        tmp_path / "Bad.yaml",
        "parts.NoSuchPartAnywhere:\n    name: x\n"
        "controller.NoSuchControllerAnywhere:\n",
    )
    status, out, _ = run(capsys, bad)
    assert status == 1
    assert out[0].startswith(f"{bad}:1: unknown section type 'parts.NoSuchPart")
    assert out[1].startswith(f"{bad}:3: unknown section type 'controller.NoSuch")


def test_definitions_are_expanded_with_their_children(capsys, tmp_path):
    blocks = tmp_path / "blocks"
    write(blocks / "t/Child.yaml", "init.Int:\n    name: n\n    required: true\n")
    parent = write(
        blocks / "t/Parent.yaml",
        "init.String:\n    name: prefix\n    required: true\n"
        "block.t.Child:\n    name: c1\n    n: {prefix}\n"
        "block.t.Missing:\n    name: c2\n",
    )
    status, out, _ = run(capsys, parent)
    assert status == 1
    text = "\n".join(out)
    assert f"{parent}:" in text
    assert "parameter 'n' must be" in text  # {prefix} is a String, n an Int
    assert "no definition 't.Missing'" in text


def test_child_definitions_found_with_search_path(capsys, tmp_path):
    write(tmp_path / "lib/x/Child.yaml", "init.String:\n    name: a\n")
    parent = write(
        tmp_path / "mine/Parent.yaml",
        "init.String:\n    name: greeting\n    default: hi\n"
        "block.x.Child:\n    name: c\n    a: '{greeting}'\n",
    )
    assert run(capsys, parent)[0] == 1
    status, out, _ = run(capsys, "-I", tmp_path / "lib", parent)
    assert (status, out) == (0, [])


def test_block_cycles_are_reported(capsys):
    status, out, _ = run(capsys, FIXTURES / "blocks/cycle/A.yaml")
    assert status == 1 and "cycle of block includes" in out[0]


# ---- process files


def test_process_file_problems(capsys):
    dup = FIXTURES / "process/duplicate_mri.yaml"
    status, out, _ = run(capsys, dup)
    assert status == 1
    assert f"{dup}:8: mri 'BL18I:DRV' is used twice" in "\n".join(out)


def test_process_include_cycle(capsys):
    status, out, _ = run(capsys, FIXTURES / "process/cycle_a.yaml")
    assert status == 1 and "cycle of includes" in out[0]


def test_process_with_unknown_definition(capsys, tmp_path):
    proc = write(tmp_path / "p.yaml", "block.nowhere.Thing:\n    mri: A:B\n")
    status, out, _ = run(capsys, proc)
    assert status == 1
    assert out[0].startswith(f"{proc}:1: no definition 'nowhere.Thing'")


def test_a_good_process_file_is_ok(capsys, tmp_path):
    write(
        tmp_path / "blocks/t/Plain.yaml",
        "init.String:\n    name: greeting\n    default: hi\n",
    )
    proc = write(
        tmp_path / "proc.yaml",
        "define.String:\n    name: bl\n    value: BL18I\n"
        "block.t.Plain:\n    mri: '{bl}:PLAIN'\n",
    )
    status, out, err = run(capsys, proc)  # blocks/ next to the file is searched
    assert (status, out) == (0, []), err


def test_bad_values_in_a_process_file(capsys, tmp_path):
    write(tmp_path / "blocks/t/Num.yaml", "init.Int:\n    name: n\n")
    proc = write(
        tmp_path / "proc.yaml",
        "block.t.Num:\n    mri: A\n    n: lots\n    nn: 1\n",
    )
    status, out, _ = run(capsys, proc)
    assert status == 1
    assert any(line.startswith(f"{proc}:3:") for line in out)
    assert any(line.startswith(f"{proc}:4:") for line in out)


# ---- models and designs


def test_builtin_models_are_ok(capsys):
    status, out, err = run(capsys, *sorted(MODELS.glob("*.yaml")))
    assert (status, out) == (0, []), err


@pytest.mark.parametrize(
    ("stem", "message"),
    [
        ("busy_cannot_abort", "busy state Calibrating cannot abort"),
        ("unreachable_state", "state Calibrating is unreachable"),
        ("undeclared_phase", "phase 'Calibrate' is not declared"),
        ("cycle_a", "extends cycle"),
    ],
)
def test_model_defects(capsys, stem, message):
    status, out, _ = run(capsys, MODEL_DEFECTS / f"{stem}.yaml")
    assert status == 1
    assert message in "\n".join(out)


def test_model_yaml_errors_have_a_line(capsys, tmp_path):
    model = write(tmp_path / "m.yaml", "name: M\nstates:\n  A: {busy: [\n")
    status, out, _ = run(capsys, model)
    assert status == 1 and out[0].startswith(f"{model}:")


def test_the_design_document_design_is_ok(capsys):
    status, out, err = run(capsys, FIXTURES / "designs/PositionBased.yaml")
    assert (status, out) == (0, []), err


def test_a_broken_design(capsys, tmp_path):
    design = write(
        tmp_path / "d.yaml",
        "parts.PalettePart:\n    name: A\n    xcoord: [oops\n",
    )
    status, out, _ = run(capsys, design)
    assert status == 1 and out[0].startswith(f"{design}:")


# ---- files that are not what they should be


def test_missing_file_directory_and_non_yaml(capsys, tmp_path):
    missing = tmp_path / "missing.yaml"
    (tmp_path / "d").mkdir()
    binary = tmp_path / "binary.yaml"
    binary.write_bytes(b"init.String:\n  name: \xff\xfe\n")
    garbage = write(tmp_path / "garbage.yaml", "a: b\n  c: [d\n\t}\n")
    status, out, err = run(capsys, missing, tmp_path / "d", binary, garbage)
    assert status == 1
    assert out[0] == f"{missing}: cannot read file: No such file or directory"
    assert out[1] == f"{tmp_path / 'd'}: a directory with no YAML files"
    assert out[2].startswith(f"{binary}:2: file is not UTF-8")
    assert out[3].startswith(f"{garbage}:") and "YAML error" in out[3]
    assert "4 problems in 4 of 4 files" in err


def test_empty_file_is_an_empty_definition(capsys, tmp_path):
    assert run(capsys, write(tmp_path / "empty.yaml", ""))[0] == 0


def test_kind_can_be_forced(capsys, tmp_path):
    text = "name: M\n"  # a model without states, read as a definition by default
    path = write(tmp_path / "m.yaml", text)
    status, out, _ = run(capsys, path)
    assert status == 1 and "must be a mapping" in out[0]
    status, out, _ = run(capsys, "--kind", "model", path)
    assert status == 1 and "must be a mapping" not in "\n".join(out)


def test_internal_errors_are_reported_not_raised(capsys, monkeypatch, tmp_path):
    def boom(*args, **kwargs):
        raise ZeroDivisionError("boom")

    monkeypatch.setattr(checks, "_check_definition", boom)
    path = write(tmp_path / "d.yaml", "init.String:\n    name: a\n")
    status, out, _ = run(capsys, path)
    assert status == 1
    assert out == [f"{path}: internal error: ZeroDivisionError: boom"]


def test_verbose_says_how_each_file_went(capsys):
    status, _, err = run(capsys, "-v", MODELS / "stateful.yaml")
    assert status == 0
    assert f"{MODELS / 'stateful.yaml'}: ok (model)" in err


def test_finding_format():
    assert str(Finding("f.yaml", 3, "bad\nthing")) == "f.yaml:3: bad\\nthing"
    assert str(Finding("f.yaml", None, "")) == "f.yaml: (no message)"
    assert str(Finding("", 1, "x")) == "<unknown>:1: x"


def test_needs_a_file(capsys):
    assert main(["check"]) == 2
    assert "FILE" in capsys.readouterr().err


def test_installed_command_exit_status_and_streams(tmp_path):
    bad = write(tmp_path / "bad.yaml", "init.Int:\n    name: n\n    default: x\n")
    result = subprocess.run(
        [sys.executable, "-m", "malcolm", "check", str(bad)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 1
    assert result.stdout == f"{bad}:3: default 'x' is not an Int\n"
    assert "1 problem in 1 of 1 file" in result.stderr
    assert "Traceback" not in result.stderr


# ---- building (malcolm.config.build), without starting anything


@pytest.fixture
def builder():
    return pytest.importorskip(
        "malcolm.config.build", reason="malcolm.config.build has not landed yet"
    )


def test_definition_that_cannot_be_built(capsys, tmp_path, builder):
    path = write(
        tmp_path / "d.yaml",
        "parts.HelloPart:\n    name: hello\n    bogus: 1\n"
        "parts.CounterPart:\n    name: counter\n",
    )
    status, out, _ = run(capsys, path)
    assert status == 1
    assert out and out[0].startswith(f"{path}:") and "bogus" in out[0]


def test_process_that_cannot_be_built(capsys, tmp_path, builder):
    write(
        tmp_path / "blocks/t/Two.yaml",
        "parts.CounterPart:\n    name: c\nparts.CounterPart:\n    name: c\n",
    )
    proc = write(tmp_path / "proc.yaml", "block.t.Two:\n    mri: T:TWO\n")
    status, out, _ = run(capsys, proc)
    assert status == 1 and out


def test_the_packaged_blocks_and_demo_process_are_ok(capsys, builder):
    files = sorted((ROOT / "malcolm/blocks").rglob("*.yaml"))
    if not files:
        pytest.skip("no definitions in malcolm/blocks yet")
    status, out, err = run(capsys, *files)
    assert (status, out) == (0, []), err


def test_model_with_a_character_yaml_forbids(capsys, tmp_path):
    model = write(tmp_path / "m.yaml", "name: M\n# \x1f\nstates: {}\n")
    status, out, _ = run(capsys, model)
    assert status == 1
    assert out[0].startswith(f"{model}:2: YAML error:")


def test_directories_are_checked_file_by_file(capsys, tmp_path):
    write(tmp_path / "blocks/t/Good.yaml", "init.String:\n    name: a\n")
    write(tmp_path / "blocks/t/Bad.yml", "init.Int:\n    name: n\n    default: x\n")
    write(tmp_path / "blocks/notes.txt", "not checked\n")
    status, out, err = run(capsys, tmp_path / "blocks")
    assert status == 1
    assert out == [f"{tmp_path}/blocks/t/Bad.yml:3: default 'x' is not an Int"]
    assert "1 problem in 1 of 2 files" in err

"""Process files: includes, defines and the blocks to make."""

import textwrap
from pathlib import Path

import pytest

from malcolm.config.errors import ConfigError
from malcolm.config.process_file import expand_process, load_process_file

FIXTURES = Path(__file__).parent / "config_fixtures"
PROCESS = FIXTURES / "process"
SEARCH = [FIXTURES / "blocks"]


def write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def test_beamline_process_file():
    spec = load_process_file(PROCESS / "beamline.yaml", SEARCH)
    assert spec.defines == {"beamline": "BL18I", "detprefix": "BL18I-EA-DET-01"}
    assert [(b.definition, b.mri, b.line) for b in spec.blocks] == [
        ("ADCore.DetectorDriver", "BL18I:DRV", 3),
        ("demo.DetectorManager", "BL18I:DET", 7),
        ("demo.GenericScan", "BL18I:SCAN", 11),
    ]
    assert spec.blocks[0].values == {"prefix": "BL18I-EA-DET-01"}
    assert spec.blocks[2].values["det"] == "BL18I:DET"
    assert spec.blocks[0].file == str(PROCESS / "beamline.yaml")
    blocks = expand_process(spec, SEARCH)
    assert [b.mri for block in blocks for b in block.walk()] == [
        "BL18I:DRV",
        "BL18I:DET",
        "BL18I:DET:pos",
        "BL18I:SCAN",
    ]
    assert blocks[1].children[0].block.sections[0].params["pv"] == (
        "BL18I-EA-DET-01:POS:Delete"
    )


def test_duplicate_mri_names_both_lines():
    with pytest.raises(ConfigError) as info:
        load_process_file(PROCESS / "duplicate_mri.yaml", SEARCH)
    file = PROCESS / "duplicate_mri.yaml"
    assert str(info.value) == (
        f"{file}:8: mri 'BL18I:DRV' is used twice (first at {file}:3)"
    )


def test_include_cycle():
    with pytest.raises(ConfigError) as info:
        load_process_file(PROCESS / "cycle_a.yaml", SEARCH)
    (problem,) = info.value.problems
    assert (problem.file, problem.line) == (str(PROCESS / "cycle_b.yaml"), 5)
    assert problem.message.startswith("cycle of includes: ")
    assert "cycle_a.yaml:1 -> " in problem.message


def test_defines_are_typed_ordered_and_unique(tmp_path):
    path = write(
        tmp_path,
        "p.yaml",
        """\
        define.Int:
            name: n
            value: 3
        define.Float:
            name: t
            value: {n}
        define.Int:
            name: bad
            value: three
        define.String:
            name: n
            value: again
        define.Str:
            name: s
            value: x
        define.String:
            name: later
            value: {undefined}
        """,
    )
    with pytest.raises(ConfigError) as info:
        load_process_file(path, SEARCH)
    assert [(p.line, p.message) for p in info.value.problems] == [
        (9, "value of 'bad' must be an Int, not 'three'"),
        (10, f"'n' is defined twice (first at {path}:1)"),
        (
            13,
            "unknown define type 'define.Str' "
            "(expected define.String, define.Int, define.Float, define.Boolean)",
        ),
        (18, "unknown parameter '{undefined}' in 'value'"),
    ]


def test_blocks_are_checked_against_their_definitions(tmp_path):
    path = write(
        tmp_path,
        "p.yaml",
        """\
        block.ADCore.DetectorDriver:
            mri: A
        block.ADCore.DetectorDriver:
            mri: B
            prefix: 5
            prefx: X
        block.ADCore.Nope:
            mri: C
        block.ADCore.PositionPlugin:
            prefix: X
        parts.Thing:
            name: x
        """,
    )
    with pytest.raises(ConfigError) as info:
        load_process_file(path, SEARCH)
    assert [(p.line, p.message.split(" (")[0]) for p in info.value.problems] == [
        (1, "ADCore.DetectorDriver: missing required parameter 'prefix'"),
        (5, "ADCore.DetectorDriver: parameter 'prefix' must be a String, not 5"),
        (6, "ADCore.DetectorDriver: unknown parameter 'prefx'"),
        (7, "no definition 'ADCore.Nope'"),
        (9, "block.ADCore.PositionPlugin needs an 'mri'"),
        (11, "unknown section 'parts.Thing' in a process file"),
    ]


def test_includes_see_earlier_defines_and_are_read_once(tmp_path):
    write(tmp_path, "shared.yaml", "define.String:\n  name: bl\n  value: BL01\n")
    (tmp_path / "sub").mkdir()
    write(
        tmp_path,
        "sub/det.yaml",
        """\
        include: ../shared.yaml
        block.ADCore.DetectorDriver:
            mri: {bl}:{where}
            prefix: {bl}-DET
        """,
    )
    path = write(
        tmp_path,
        "main.yaml",
        """\
        define.String:
            name: where
            value: EH1
        include:
          - shared.yaml
          - sub/det.yaml
        """,
    )
    spec = load_process_file(path, SEARCH)
    assert [(b.mri, b.values) for b in spec.blocks] == [
        ("BL01:EH1", {"prefix": "BL01-DET"})
    ]
    assert spec.blocks[0].file == str(tmp_path / "sub/det.yaml")


def test_missing_include(tmp_path):
    path = write(tmp_path, "p.yaml", "include: [a.yaml, 5]\n")
    with pytest.raises(ConfigError) as info:
        load_process_file(path, SEARCH)
    assert [(p.line, p.message.split(":")[0]) for p in info.value.problems] == [
        (1, "no such file"),
        (1, "include needs a file name"),
    ]


def test_expanded_mris_must_differ(tmp_path):
    path = write(
        tmp_path,
        "p.yaml",
        """\
        block.demo.DetectorManager:
            mri: BL
            pvprefix: X
        block.ADCore.PositionPlugin:
            mri: BL:pos
            prefix: Y
        """,
    )
    spec = load_process_file(path, SEARCH)
    with pytest.raises(ConfigError) as info:
        expand_process(spec, SEARCH)
    assert str(info.value) == (
        f"{path}:4: mri 'BL:pos' is made twice "
        f"(also by demo.DetectorManager at {path}:1)"
    )

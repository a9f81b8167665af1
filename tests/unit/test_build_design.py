"""Saved designs: typed records in file order, with file:line errors."""

import textwrap
from pathlib import Path

import pytest

from malcolm.config.build import build_definition
from malcolm.config.errors import ConfigError
from malcolm.config.registry import lookup
from malcolm.parts.design import (
    ExportPart,
    FixedFloat,
    FixedInt,
    FixedTable,
    FollowerPart,
    ModelPart,
    PalettePart,
    load_design,
)

FIXTURES = Path(__file__).parent / "config_fixtures"


def write(tmp_path, text, name="d.yaml"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def test_saved_design_example():
    design = load_design(FIXTURES / "designs" / "PositionBased.yaml")
    assert design.model == "PositionBased"
    assert design.records[0] == ModelPart("PositionBased")
    assert design.palette == [
        PalettePart("PCOMP1", 12, 15, True),
        PalettePart("PCOMP2", 0, 0, False),
        PalettePart("PCAP", 200, 230, True),
    ]
    assert design.exports == [
        ExportPart("Arm", "PCAP.START", "Start the experiment"),
        ExportPart("Start", "PCOMP1.START"),
    ]
    assert design.followers == [FollowerPart("PCOMP2.START", "Start")]
    width, table = design.fixed
    assert width == FixedInt("PCOMP2.WIDTH", 32)
    assert isinstance(table, FixedTable) and table.name == "SEQ1.TABLE"
    assert table.value == [
        {"Phase1Time": 32, "Phase2Time": 45, "NRepeats": 3},
        {"Phase1Time": 3, "Phase2Time": 5, "NRepeats": 1},
    ]
    assert table.columns == ["Phase1Time", "Phase2Time", "NRepeats"]
    # in file order, with where each came from
    assert [type(r).__name__ for r in design.records] == [
        "ModelPart", "PalettePart", "PalettePart", "PalettePart", "ExportPart",
        "ExportPart", "FollowerPart", "FixedInt", "FixedTable",
    ]  # fmt: skip
    assert [line for _, line in design.lines] == [1, 4, 10, 16, 22, 27, 31, 35, 39]


def test_design_kinds_are_registered():
    assert lookup("parts.PalettePart") is PalettePart
    assert lookup("fixed.Float") is FixedFloat


def test_float_accepts_an_int(tmp_path):
    design = load_design(write(tmp_path, "fixed.Float:\n  name: A.B\n  value: 3\n"))
    assert design.records == [FixedFloat("A.B", 3.0)]
    assert isinstance(design.records[0].value, float)


def test_every_problem_at_its_line(tmp_path):
    path = write(
        tmp_path,
        """\
        parts.PalettePart:
            name: PCOMP1
            xcoord: twelve
            ycoord: 15
            visible: maybe
        parts.PaletePart:
            name: X
        fixed.Int:
            name: A.B
            value: true
        parts.ExportPart:
            name: Arm
            sorce: PCAP.START
        fixed.Table:
            name: SEQ1.TABLE
            value:
                - Phase1Time: 1
                - Phase2Time: 2
        """,
    )
    with pytest.raises(ConfigError) as info:
        load_design(path)
    assert [str(p).replace(f"{path}:", "") for p in info.value.problems] == [
        "3: parts.PalettePart: 'xcoord' must be an Int, not 'twelve'",
        "5: parts.PalettePart: 'visible' must be a Boolean (Yes/No, true/false), "
        "not 'maybe'",
        "6: unknown design section 'parts.PaletePart' "
        "(did you mean 'parts.PalettePart'?)",
        "10: fixed.Int: 'value' must be an Int, not True",
        "11: parts.ExportPart needs a 'source'",
        "13: parts.ExportPart: unknown key 'sorce' (expected name, source, "
        "description) (did you mean 'source'?)",
        "18: fixed.Table: row 2 has columns ['Phase2Time'], expected "
        "['Phase1Time'] (as in row 1)",
    ]


def test_a_design_record_in_a_block_definition_is_an_error(tmp_path):
    path = write(tmp_path, "parts.PalettePart:\n  name: P\n  xcoord: 1\n"
                 "  ycoord: 2\n  visible: Yes\n")  # fmt: skip
    with pytest.raises(ConfigError) as info:
        build_definition(path, {}, "M")
    assert str(info.value) == (
        f"{path}:1: parts.PalettePart makes PalettePart, not a Part "
        "(a saved-design record: read it with load_design)"
    )

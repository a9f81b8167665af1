"""The design document's examples parse verbatim into ordered sections."""

import textwrap
from pathlib import Path

import pytest

from malcolm.config.errors import ConfigError
from malcolm.config.yamlsections import (
    load_sections,
    parse_sections,
    quote_references,
)

FIXTURES = Path(__file__).parent / "config_fixtures"
DESIGN_DOC = Path("/work/shared/design/block-hierarchy.rst")


def kinds(sections):
    return [s.kind for s in sections]


def test_detector_driver_example():
    sections = load_sections(FIXTURES / "blocks/ADCore/DetectorDriver.yaml")
    assert kinds(sections) == [
        "init.String",
        "gui.Group",
        "ca.Double",
        "ca.LongString",
        "ca.Enum",
    ]
    init, group, double, longstring, enum = sections
    assert init.params == {
        "name": "prefix",
        "description": "PV Prefix",
        "required": True,
    }
    assert group.params["label"] == "Configuration Parameters"
    assert double.namespace == "ca" and double.name == "Double"
    assert double.params["pv"] == "{prefix}:Exposure"
    assert double.params["rbv_suffix"] == "_RBV"
    assert longstring.params["pv"] == "{prefix}:Filename"
    assert longstring.params["writeable"] is True
    assert enum.params["pv"] == "{prefix}:Acquire"
    # lines are 1-based and point at the key
    assert [s.line for s in sections] == [2, 8, 14, 22, 30]
    assert double.param_lines["pv"] == 17
    assert double.file.endswith("DetectorDriver.yaml")


def test_manager_example():
    sections = load_sections(FIXTURES / "blocks/demo/DetectorManager.yaml")
    assert kinds(sections) == [
        "init.String",
        "controller.AreaDetectorController",
        "block.ADCore.PositionPlugin",
        "client.ADCore.DetectorDriver",
    ]
    block, client = sections[2:]
    assert block.namespace == "block"
    assert block.name == "ADCore.PositionPlugin"
    assert block.params == {
        "name": "pos",
        "prefix": "{pvprefix}",
        "part": "PosPluginPart",
    }
    assert client.params == {
        "name": "drv",
        "fullname": "sim:drv",
        "part": "DriverRunPart",
        "readonly": False,
    }


def test_saved_design_keeps_repeated_keys_in_order():
    sections = load_sections(FIXTURES / "designs/PositionBased.yaml")
    assert kinds(sections) == [
        "parts.ModelPart",
        "parts.PalettePart",
        "parts.PalettePart",
        "parts.PalettePart",
        "parts.ExportPart",
        "parts.ExportPart",
        "parts.FollowerPart",
        "fixed.Int",
        "fixed.Table",
    ]
    palette = [s.params for s in sections if s.kind == "parts.PalettePart"]
    assert palette == [
        {"name": "PCOMP1", "xcoord": 12, "ycoord": 15, "visible": True},
        {"name": "PCOMP2", "xcoord": 0, "ycoord": 0, "visible": False},
        {"name": "PCAP", "xcoord": 200, "ycoord": 230, "visible": True},
    ]
    assert [s.line for s in sections if s.kind == "parts.PalettePart"] == [4, 10, 16]
    exports = [s.params for s in sections if s.kind == "parts.ExportPart"]
    assert exports[0] == {
        "name": "Arm",
        "source": "PCAP.START",
        "description": "Start the experiment",
    }
    assert exports[1] == {"name": "Start", "source": "PCOMP1.START"}
    assert sections[6].params == {"name": "PCOMP2.START", "source": "Start"}
    assert sections[7].params == {"name": "PCOMP2.WIDTH", "value": 32}
    table = sections[8]
    assert table.params["value"] == [
        {"Phase1Time": 32, "Phase2Time": 45, "NRepeats": 3},
        {"Phase1Time": 3, "Phase2Time": 5, "NRepeats": 1},
    ]
    # every nested value knows its line
    assert table.line_of(("value", 1, "Phase2Time")) == 46
    assert table.line_of(("value", 0)) == 42
    assert table.line == 39 and table.param_lines["value"] == 41


def test_coordination_example():
    sections = load_sections(FIXTURES / "blocks/demo/GenericScan.yaml")
    assert kinds(sections) == [
        "init.ADCore.DetectorDriver",
        "init.zebra2.Zebra",
        "init.motor.MotorController",
        "controller.GenericScanController",
        "parts.DetectorPart",
        "parts.ZebraPart",
        "parts.MotorPart",
    ]
    assert sections[0].name == "ADCore.DetectorDriver"
    # an empty body means no parameters
    assert sections[3].params == {}
    assert [s.params["input"] for s in sections[4:]] == ["{det}", "{zebra}", "{motor}"]


@pytest.mark.skipif(not DESIGN_DOC.exists(), reason="design document not present")
@pytest.mark.parametrize(
    "marker, fixture",
    [
        ("This is a detector driver block::", "blocks/ADCore/DetectorDriver.yaml"),
        ("when they are constructed::", "blocks/demo/DetectorManager.yaml"),
        ("will also be written in YAML::", "designs/PositionBased.yaml"),
        ("generic case might look like this::", "blocks/demo/GenericScan.yaml"),
    ],
)
def test_fixtures_are_verbatim_copies(marker, fixture):
    lines = DESIGN_DOC.read_text().split("\n")
    start = next(i for i, line in enumerate(lines) if line.endswith(marker))
    block = []
    for line in lines[start + 1 :]:
        if line.strip() and not line.startswith("    "):
            break
        block.append(line)
    example = textwrap.dedent("\n".join(block)).strip("\n") + "\n"
    assert (FIXTURES / fixture).read_text() == example


def test_references_in_plain_values():
    text = textwrap.dedent(
        """\
        parts.Demo:
            a: {x}:y  # comment
            b: {x}
            c: [{x}, {y}]
            d:
              - {x}:z
              - key: {x}{y}
            e: "{x}"
            f: |
              keep: {x}:y
            g: {a: 1, b: 2}
        """
    )
    (section,) = parse_sections(text, "t.yaml")
    assert section.params == {
        "a": "{x}:y",
        "b": "{x}",
        "c": ["{x}", "{y}"],
        "d": ["{x}:z", {"key": "{x}{y}"}],
        "e": "{x}",
        "f": "keep: {x}:y\n",
        "g": {"a": 1, "b": 2},
    }
    assert section.line_of(("d", 1, "key")) == 7


def test_quote_references_keeps_lines():
    text = "a: {x}:y\n- {p}-{q}  # c\nb: |\n  {x}:y\nc: {x}:it's\n"
    quoted = quote_references(text)
    assert quoted == "a: '{x}:y'\n- '{p}-{q}'  # c\nb: |\n  {x}:y\nc: '{x}:it''s'\n"
    assert quoted.count("\n") == text.count("\n")


def test_empty_document_has_no_sections():
    assert parse_sections("# nothing\n", "e.yaml") == []


@pytest.mark.parametrize(
    "text, line, message",
    [
        ("- a\n- b\n", 1, "a definition must be a mapping of sections"),
        ("ca.Double:\n  name: a\n  name: b\n", 3, "duplicate parameter 'name'"),
        ("ca.Double: [1, 2]\n", 1, "body of ca.Double must be a mapping"),
        ("ca.Double:\n  x: &a 1\n  y: *a\n", 3, "aliases (*name) are not supported"),
        ("ca.Double:\n  x: 1\n y: 2\n", 3, "YAML error"),
        ("ca.Double:\n  x: 2020-99-99\n", 2, "bad value"),
        ("ca.Double:\n  x: !!set {a, b}\n", 2, "unsupported YAML tag"),
        ("ca.Double:\n  x: {a: 1, a: 2}\n", 2, "duplicate key 'a'"),
        ("x y z:\n  a: 1\n", 1, "invalid section name 'x y z'"),
        ("ca.Double:\n  x: 1\n  y: \x07\n", 3, "special characters"),
        ("ca.Double:\n  x: 1\n---\nca.Enum:\n", 3, "single document"),
    ],
)
def test_errors_name_file_and_line(text, line, message):
    with pytest.raises(ConfigError) as info:
        parse_sections(text, "bad.yaml")
    problem = info.value.problems[0]
    assert (problem.file, problem.line) == ("bad.yaml", line)
    assert message in problem.message
    assert str(info.value).startswith(f"bad.yaml:{line}: ")


def test_all_problems_reported_at_once():
    text = "ca.A:\n  x: 1\n  x: 2\nca.B: 5\nca.C:\n  y: 1\n  y: 2\n"
    with pytest.raises(ConfigError) as info:
        parse_sections(text, "many.yaml")
    assert [p.line for p in info.value.problems] == [3, 4, 7]
    assert str(info.value).splitlines()[1].startswith("many.yaml:4: ")


def test_missing_file_is_a_config_error(tmp_path):
    with pytest.raises(ConfigError, match=r"nope.yaml:1: cannot read file"):
        load_sections(tmp_path / "nope.yaml")


def test_value_kinds_allow_non_mapping_bodies():
    (section,) = parse_sections("include: [a.yaml, b.yaml]\n", value_kinds={"include"})
    assert section.namespace == "include" and section.name == ""
    assert section.params == {"value": ["a.yaml", "b.yaml"]}

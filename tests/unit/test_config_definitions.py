"""Finding, loading and expanding block definitions."""

import textwrap
from pathlib import Path

import pytest

from malcolm.config.definitions import (
    BLOCKS_DIR,
    available_definitions,
    expand,
    find_definition,
    full_search_path,
    load_definition,
)
from malcolm.config.errors import ConfigError

FIXTURES = Path(__file__).parent / "config_fixtures"
BLOCKS = FIXTURES / "blocks"
SEARCH = [BLOCKS]


def load(name):
    return load_definition(find_definition(name, SEARCH), name=name)


def write(tmp_path, name, text):
    path = tmp_path.joinpath(*name.split(".")).with_suffix(".yaml")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(textwrap.dedent(text))
    return path


def test_search_path_starts_with_the_package_blocks():
    assert full_search_path([BLOCKS, BLOCKS]) == [BLOCKS_DIR, BLOCKS]
    # the package's own definitions come first (the detector manager fixture
    # uses the packaged ADCore.PositionPlugin and ADCore.DetectorDriver)
    assert find_definition("ADCore.PositionPlugin", SEARCH) == (
        BLOCKS_DIR / "ADCore" / "PositionPlugin.yaml"
    )
    assert "demo.DetectorManager" in available_definitions(SEARCH)


def test_missing_definition():
    with pytest.raises(ConfigError) as info:
        find_definition("ADCore.PositonPlugin", SEARCH, file="m.yaml", line=9)
    message = str(info.value)
    assert message.startswith("m.yaml:9: no definition 'ADCore.PositonPlugin'")
    assert "did you mean 'ADCore.PositionPlugin'?" in message
    with pytest.raises(ConfigError, match="invalid definition name"):
        find_definition("../etc/passwd", SEARCH, file="m.yaml", line=9)


def test_detector_driver_expands_with_prefix():
    definition = load("ADCore.DetectorDriver")
    assert [p.name for p in definition.params] == ["prefix"]
    assert definition.params[0].required
    block = expand(definition, {"prefix": "BL18I-DET"}, SEARCH, mri="BL18I:DRV")
    assert block.mri == "BL18I:DRV"
    assert [g.params["name"] for g in block.groups] == ["configuration"]
    # the design document's three sections first, then the packaged extras
    kinds = [s.kind for s in block.sections]
    assert kinds[:3] == ["ca.Double", "ca.LongString", "ca.Enum"]
    assert [s.params["pv"] for s in block.sections[:3]] == [
        "BL18I-DET:Exposure",
        "BL18I-DET:Filename",
        "BL18I-DET:Acquire",
    ]
    assert block.controller is None and block.children == []


def test_manager_expands_children_and_records_clients():
    definition = load("demo.DetectorManager")
    block = expand(definition, {"pvprefix": "BL18I-DET"}, SEARCH, mri="BL18I:DET")
    assert block.controller.kind == "controller.AreaDetectorController"
    assert block.controller.params == {"design": "simDetectorDefaultSetup"}
    (child,) = block.children
    assert (child.name, child.part, child.line) == ("pos", "PosPluginPart", 9)
    assert child.block.mri == "BL18I:DET:pos"
    assert child.block.definition == "ADCore.PositionPlugin"
    assert child.block.params == {"prefix": "BL18I-DET"}
    pvs = {s.params["name"]: s.params.get("pv") for s in child.block.sections}
    assert pvs["xml"] == "BL18I-DET:POS:Filename"
    (client,) = block.clients
    assert client.definition == "ADCore.DetectorDriver"
    assert (client.name, client.fullname, client.part) == (
        "drv",
        "sim:drv",
        "DriverRunPart",
    )
    assert client.params == {"readonly": False}
    assert [b.mri for b in block.walk()] == ["BL18I:DET", "BL18I:DET:pos"]


def test_missing_required_param_of_a_child_names_the_block_section():
    definition = load("demo.DetectorManager")
    with pytest.raises(ConfigError) as info:
        expand(definition, {}, SEARCH, mri="M")
    assert str(info.value) == (
        f"{BLOCKS / 'demo/DetectorManager.yaml'}:9: ADCore.PositionPlugin: "
        "missing required parameter 'prefix' (PV Prefix)"
    )


def test_missing_required_param_at_top_level():
    with pytest.raises(ConfigError) as info:
        expand(load("ADCore.DetectorDriver"), {}, SEARCH, file="p.yaml", line=4)
    assert str(info.value) == (
        "p.yaml:4: ADCore.DetectorDriver: missing required parameter 'prefix' "
        "(PV Prefix)"
    )


def test_coordination_block_references():
    definition = load("demo.GenericScan")
    assert [p.type for p in definition.params] == [
        "ADCore.DetectorDriver",
        "zebra2.Zebra",
        "motor.MotorController",
    ]
    values = {"det": "BL18I:DET", "zebra": "BL18I:Z1", "motor": "BL18I:MOT"}
    block = expand(definition, values, SEARCH, mri="BL18I:SCAN")
    assert block.controller.params == {}
    assert [(s.kind, s.params) for s in block.sections] == [
        ("parts.DetectorPart", {"input": "BL18I:DET"}),
        ("parts.ZebraPart", {"input": "BL18I:Z1"}),
        ("parts.MotorPart", {"input": "BL18I:MOT"}),
    ]
    with pytest.raises(ConfigError, match="parameter 'det' must be an mri"):
        expand(definition, {**values, "det": 5}, SEARCH)


def test_saved_design_loads_as_a_definition_without_params():
    definition = load_definition(FIXTURES / "designs/PositionBased.yaml")
    block = expand(definition, {}, mri="BL18I:Z1")
    assert len(block.sections) == 9
    assert block.sections[3].params["visible"] is True


def test_cycle_of_block_includes():
    with pytest.raises(ConfigError) as info:
        expand(load("cycle.A"), {"prefix": "X"}, SEARCH, mri="M")
    (problem,) = info.value.problems
    assert problem.file == str(BLOCKS / "cycle/B.yaml")
    assert problem.line == 4
    assert "cycle of block includes: cycle.A -> cycle.B -> cycle.A" in problem.message
    assert f"{BLOCKS / 'cycle/A.yaml'}:4" in problem.message


def test_self_include_is_a_cycle(tmp_path):
    write(tmp_path, "loop.Self", "block.loop.Self:\n  name: again\n")
    definition = load_definition(tmp_path / "loop/Self.yaml", name="loop.Self")
    with pytest.raises(ConfigError, match=r"Self.yaml:1: cycle of block includes"):
        expand(definition, {}, [tmp_path])


def test_broken_definition_reports_every_problem_in_line_order():
    with pytest.raises(ConfigError) as info:
        load_definition(BLOCKS / "demo/Broken.yaml")
    file = BLOCKS / "demo/Broken.yaml"
    assert str(info.value).splitlines() == [
        f"{file}:3: default 'lots' is not an Int",
        f"{file}:7: unknown parameter '{{prefx}}' in 'pv'",
        f"{file}:9: unknown section type 'gui.Grop' (did you mean 'gui.Group'?)",
    ]


def test_expansion_collects_problems_across_children(tmp_path):
    write(
        tmp_path,
        "top.Parent",
        """\
        init.String:
            name: prefix
        block.top.Child:
            name: one
        block.top.Missing:
            name: two
        block.top.Child:
            name: three
            count: many
        block.top.Child:
            name: one
        client.top.Child:
            name: four
        """,
    )
    write(
        tmp_path,
        "top.Child",
        """\
        init.String:
            name: prefix
            required: true
        init.Int:
            name: count
        parts.P:
            pv: {prefix}:{count}
        """,
    )
    parent = tmp_path / "top/Parent.yaml"
    with pytest.raises(ConfigError) as info:
        load_definition(parent)
    assert str(info.value) == f"{parent}:12: client.top.Child needs a 'fullname' (text)"
    parent.write_text(
        parent.read_text().replace("name: four", "name: x\n    fullname: y")
    )
    with pytest.raises(ConfigError) as info:
        expand(load_definition(parent), {}, [tmp_path], mri="T")
    messages = [(p.line, p.message.split(" (")[0]) for p in info.value.problems]
    assert messages == [
        (3, "top.Child: missing required parameter 'prefix'"),
        (5, "no definition 'top.Missing'"),
        (7, "top.Child: missing required parameter 'prefix'"),
        (9, "top.Child: parameter 'count' must be an Int, not 'many'"),
        (10, "two children named 'one'"),
    ]


def test_child_values_with_no_value_in_a_longer_string(tmp_path):
    write(tmp_path, "a.Child", "init.String:\n  name: p\nparts.P:\n  pv: x{p}\n")
    with pytest.raises(ConfigError, match=r"Child.yaml:4: parameter 'p' has no value"):
        expand(load_definition(tmp_path / "a/Child.yaml"), {}, [tmp_path])


@pytest.mark.parametrize(
    "text, line, message",
    [
        ("controller.A:\ncontroller.B:\n", 2, "a block has one controller"),
        ("init.String:\n  name: a\ninit.Int:\n  name: a\n", 3, "declared twice"),
        ("ca.Double:\n  group: nope\ngui.Group:\n  name: g\n", 2, "unknown group"),
        ("block.ADCore.PositionPlugin:\n  prefix: x\n", 1, "needs a 'name'"),
        ("parts:\n  name: x\n", 1, "must be written namespace.Name"),
        ("parts.P:\n  pv: {nope}\n", 2, "unknown parameter '{nope}'"),
    ],
)
def test_definition_errors(tmp_path, text, line, message):
    path = write(tmp_path, "x.Bad", text)
    with pytest.raises(ConfigError) as info:
        load_definition(path)
    assert str(info.value).startswith(f"{path}:{line}: ")
    assert message in str(info.value)


def test_mri_is_always_available(tmp_path):
    path = write(tmp_path, "x.Mri", "parts.P:\n  name: {mri}-part\n")
    block = expand(load_definition(path), {}, mri="BL:X")
    assert block.sections[0].params == {"name": "BL:X-part"}

"""Mistakes in definitions and process files: file:line errors, nothing built."""

import textwrap
from pathlib import Path

import pytest

from malcolm.config.build import build_definition, build_process
from malcolm.config.errors import ConfigError
from malcolm.core import Process

FIXTURES = Path(__file__).parent / "config_fixtures"
SEARCH = [FIXTURES / "blocks"]


def write(tmp_path, name, text):
    path = tmp_path.joinpath(*name.split("/"))
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(textwrap.dedent(text))
    return path


@pytest.fixture
def process():
    """A process that already serves one block: errors must leave it alone."""
    process = build_definition("demo.Counter", {}, "EXISTING")
    assert process.mris == ["EXISTING"]
    yield process
    assert process.mris == ["EXISTING"]


def problems(info, tmp_path=None):
    out = [str(p) for p in info.value.problems]
    if tmp_path is not None:
        out = [p.replace(f"{tmp_path}/", "") for p in out]
    return out


def test_missing_required_param(tmp_path, process):
    path = write(
        tmp_path,
        "p.yaml",
        """\
        block.demo.Counter:
            mri: C
        block.ADCore.DetectorDriver:
            mri: DRV
        """,
    )
    with pytest.raises(ConfigError) as info:
        build_process(path, SEARCH, process=process)
    assert problems(info, tmp_path) == [
        "p.yaml:3: ADCore.DetectorDriver: missing required parameter 'prefix' "
        "(PV Prefix)"
    ]
    with pytest.raises(ConfigError, match="missing required parameter 'prefix'"):
        build_definition("ADCore.DetectorDriver", {}, "DRV", SEARCH, process=process)


def test_unknown_section_type(tmp_path, process):
    write(
        tmp_path,
        "lab/Box.yaml",
        """\
        ca.Double:
            name: a
            pv: A
        ca.Dubble:
            name: b
            pv: B
        parts.NoSuchPart:
        controller.StatefulControler:
        """,
    )
    with pytest.raises(ConfigError) as info:
        build_definition("lab.Box", {}, "BOX", [tmp_path], process=process)
    assert problems(info, tmp_path) == [
        "lab/Box.yaml:4: unknown section type 'ca.Dubble' (did you mean 'ca.Double'?)",
        "lab/Box.yaml:7: unknown section type 'parts.NoSuchPart'",
        "lab/Box.yaml:8: unknown section type 'controller.StatefulControler' "
        "(did you mean 'controller.StatefulController'?)",
    ]


def test_bad_value_types(tmp_path, process):
    write(
        tmp_path,
        "lab/Box.yaml",
        """\
        init.Int:
            name: count
            default: lots
        """,
    )
    with pytest.raises(ConfigError) as info:
        build_definition("lab.Box", {}, "BOX", [tmp_path], process=process)
    assert problems(info, tmp_path) == ["lab/Box.yaml:3: default 'lots' is not an Int"]

    write(
        tmp_path,
        "lab/Motor.yaml",
        """\
        parts.SimMotorPart:
            name: m
            velocity: fast
        ca.Enum:
            name: mode
            pv: X:Mode
            choices: 5
        """,
    )
    with pytest.raises(ConfigError) as info:
        build_definition("lab.Motor", {}, "M", [tmp_path], process=process)
    assert problems(info, tmp_path) == [
        # the keyword's annotation is checked first, at the key's own line
        "lab/Motor.yaml:3: parts.SimMotorPart: 'velocity' must be a number, not 'fast'",
        "lab/Motor.yaml:4: ca.Enum: choices must be a list of text, not 5",
    ]

    with pytest.raises(ConfigError) as info:
        build_definition("demo.Motor", {"velocity": "fast"}, "M", process=process)
    assert (
        problems(info)
        == ["<search>:1: demo.Motor: parameter 'velocity' must be a Float, not 'fast'"]
        or "must be a Float" in problems(info)[0]
    )


def test_unknown_keyword_and_failing_constructor(tmp_path, process):
    write(
        tmp_path,
        "lab/Box.yaml",
        """\
        controller.RunnableController:
            description: A box
            colour: red
        ca.Double:
            name: exposure
            pvv: X:Exposure
        ca.Double:
            name: gain
        parts.HelloPart:
        """,
    )
    with pytest.raises(ConfigError) as info:
        build_definition("lab.Box", {}, "BOX", [tmp_path], process=process)
    found = problems(info, tmp_path)
    assert found[0].startswith(
        "lab/Box.yaml:3: controller.RunnableController: unknown parameter 'colour' "
        "(RunnableController takes mri, parts, description, designs_dir"
    )
    assert found[1:] == [
        "lab/Box.yaml:6: ca.Double: unknown parameter 'pvv' (CADoublePart takes "
        "name, pv, rbv, rbv_suffix, description, widget, group, writeable, label, "
        "low, high, units, precision) (did you mean 'pv'?)",
        "lab/Box.yaml:7: ca.Double: needs a 'pv' or an 'rbv'",
    ]


def test_a_field_or_part_made_twice(tmp_path, process):
    write(
        tmp_path,
        "lab/Box.yaml",
        """\
        ca.Double:
            name: exposure
            pv: A
        ca.Long:
            name: exposure
            pv: B
        ca.String:
            name: state
            pv: C
        parts.CounterPart:
            name: counter
        """,
    )
    with pytest.raises(ConfigError) as info:
        build_definition("lab.Box", {}, "BOX", [tmp_path], process=process)
    assert problems(info, tmp_path) == [
        "lab/Box.yaml:4: ca.Long: BOX already has a part called 'exposure' (line 1)",
        "lab/Box.yaml:7: ca.String: 'state' is already a field of BOX",
    ]


def test_missing_definition(tmp_path, process):
    path = write(tmp_path, "p.yaml", "block.demo.Hello:\n  mri: H\n"
                 "block.demo.Helo:\n  mri: H2\n")  # fmt: skip
    with pytest.raises(ConfigError) as info:
        build_process(path, SEARCH, process=process)
    (problem,) = problems(info, tmp_path)
    assert problem.startswith("p.yaml:3: no definition 'demo.Helo'")
    assert problem.endswith("(did you mean 'demo.Hello'?)")


def test_missing_client_definition(tmp_path, process):
    write(tmp_path, "lab/Box.yaml", "client.lab.Nope:\n  name: n\n  fullname: X\n")
    with pytest.raises(ConfigError) as info:
        build_definition("lab.Box", {}, "BOX", [tmp_path], process=process)
    (problem,) = problems(info, tmp_path)
    assert problem.startswith("lab/Box.yaml:1: no definition 'lab.Nope'")


def test_include_cycles(process):
    with pytest.raises(ConfigError) as info:
        build_process(FIXTURES / "process" / "cycle_a.yaml", SEARCH, process=process)
    (problem,) = info.value.problems
    assert (problem.file, problem.line) == (
        str(FIXTURES / "process" / "cycle_b.yaml"),
        5,
    )
    assert problem.message.startswith("cycle of includes: ")

    with pytest.raises(ConfigError) as info:
        build_definition("cycle.A", {"prefix": "X"}, "A", SEARCH, process=process)
    (problem,) = info.value.problems
    assert problem.file == str(FIXTURES / "blocks" / "cycle" / "B.yaml")
    assert problem.line == 4
    assert "cycle of block includes: cycle.A -> cycle.B -> cycle.A" in problem.message


def test_nothing_is_added_when_a_later_block_fails(tmp_path, process):
    write(tmp_path, "lab/Bad.yaml", "ca.Double:\n  name: x\n")
    path = write(
        tmp_path,
        "p.yaml",
        """\
        block.demo.Hello:
            mri: H
        block.demo.Detector:
            mri: D
        block.lab.Bad:
            mri: B
        """,
    )
    with pytest.raises(ConfigError) as info:
        build_process(path, [tmp_path], process=process)
    assert problems(info, tmp_path) == [
        "lab/Bad.yaml:1: ca.Double: needs a 'pv' or an 'rbv'"
    ]


def test_an_mri_that_already_exists(tmp_path, process):
    path = write(tmp_path, "p.yaml", "block.demo.Hello:\n  mri: H\n"
                 "block.demo.Counter:\n  mri: EXISTING\n")  # fmt: skip
    with pytest.raises(ConfigError) as info:
        build_process(path, process=process)
    assert problems(info, tmp_path) == [
        "p.yaml:3: a block with mri 'EXISTING' already exists in EXISTING"
    ]


def test_a_new_process_is_not_returned_on_error(tmp_path):
    path = write(tmp_path, "p.yaml", "block.demo.Hello:\n  mri: H\n  greeting: hi\n")
    with pytest.raises(ConfigError) as info:
        build_process(path, process=Process("x"))
    assert (
        problems(info, tmp_path)
        == [
            "p.yaml:3: demo.Hello: unknown parameter 'greeting' "
            "(demo.Hello takes no parameters)"
        ]
        or "unknown parameter 'greeting'" in problems(info, tmp_path)[0]
    )


def test_a_stand_in_that_needs_itself(tmp_path, process):
    write(
        tmp_path,
        "lab/Loop.yaml",
        """\
        client.lab.Loop:
            name: next
            fullname: {mri}:next
        """,
    )
    with pytest.raises(ConfigError) as info:
        build_definition("lab.Loop", {}, "L", [tmp_path], process=process)
    assert problems(info, tmp_path) == [
        "lab/Loop.yaml:1: cannot make a stand-in for 'L:next:next': lab.Loop "
        "needs stand-ins of itself (lab.Loop -> lab.Loop)"
    ]

"""The Zebra2 example's Editor: save and load, table edits, bad designs,
templates, design names, and `malcolm check` on designs.

Designs are copied into ``tmp_path``; nothing is written into the repository.
"""

from __future__ import annotations

import os
import shutil
import stat
from pathlib import Path

import pytest

from malcolm.core import BadValueError, NotAllowedError
from malcolm.editor.store import dump_design
from malcolm.parts.design import (
    FixedBool,
    FixedInt,
    PalettePart,
    load_design,
)

from .scans import run
from .test_editor_zebra2 import (
    EXAMPLE,
    MRI,
    child,
    load,
    rows,
    runnable_zebra2,
    settle,
    snapshot,
    zebra2,
)

NEW_ROWS = [
    {"Phase1Time": 1, "Phase2Time": 2, "NRepeats": 10},
    {"Phase1Time": 4, "Phase2Time": 5, "NRepeats": 6},
    {"Phase1Time": 7, "Phase2Time": 8, "NRepeats": 9},
]


def saved(tmp_path: Path, name: str) -> Path:
    return tmp_path / "designs" / "BL18I_Z1" / f"{name}.yaml"


# ---- save, then load


def test_a_save_of_the_example_is_equivalent_to_it(tmp_path):
    """Equivalent: the same model, exports and followers; the same palette
    entries plus one for each child the palette left out (SEQ1, where it is
    drawn); every fixed entry of the example with the same value, plus one
    for each other writeable child attribute that is neither exported nor
    followed (PCOMP1.WIDTH, PCAP.ARM), at its value when saved."""
    process = zebra2(tmp_path)

    async def scenario():
        await process.start()
        manager = await load(process)
        await process.post([MRI, "save"], {"design": "again"})
        assert (manager.current, manager.design.value) == ("Ready", "again")
        assert manager.modified.value is False
        await process.stop()

    run(scenario)
    original, again = load_design(EXAMPLE), load_design(saved(tmp_path, "again"))
    assert again.model == original.model == "PositionBased"
    assert again.exports == original.exports
    assert again.followers == original.followers
    assert again.palette == [*original.palette, PalettePart("SEQ1", 0, 0, True)]
    for record in original.fixed:
        assert record in again.fixed
    extra = [r for r in again.fixed if r not in original.fixed]
    assert extra == [FixedInt("PCOMP1.WIDTH", 0), FixedBool("PCAP.ARM", False)]
    # the records keep the document's order of kinds
    kinds = [type(r).__name__ for r in again.records]
    assert kinds == sorted(kinds, key=lambda k: [
        "ModelPart", "PalettePart", "ExportPart", "FollowerPart"].index(k)
        if not k.startswith("Fixed") else 9)  # fmt: skip
    # and a second save writes the same text
    text = saved(tmp_path, "again").read_text()
    assert text == dump_design(again.records)


def test_save_without_a_name_saves_the_loaded_design(tmp_path):
    process = zebra2(tmp_path)

    async def scenario():
        await process.start()
        await load(process)
        await process.post([MRI, "save"])
        await process.stop()

    run(scenario)
    written = load_design(saved(tmp_path, "example"))
    assert written.records != load_design(EXAMPLE).records  # it was saved
    assert all(r in written.fixed for r in load_design(EXAMPLE).fixed)


def test_save_then_load_reproduces_every_fixed_value_and_table(tmp_path):
    process = zebra2(tmp_path)
    # the example without its fixed SEQ1.TABLE
    text = EXAMPLE.read_text()
    saved(tmp_path, "untabled").write_text(text[: text.index("fixed.Table:")])

    async def scenario():
        await process.start()
        manager = await load(process, "untabled")
        # attributes the design does not fix: set directly
        await process.put([f"{MRI}:PCOMP1", "WIDTH"], 17)
        await process.put([f"{MRI}:PCAP", "ARM"], True)
        await process.put([f"{MRI}:SEQ1", "TABLE"], NEW_ROWS)
        await settle()
        assert manager.current == "Ready"
        await process.post([MRI, "save"], {"design": "edited"})
        await process.stop()

    run(scenario)
    design = load_design(saved(tmp_path, "edited"))
    assert {r.name: r.value for r in design.fixed} == {
        "PCOMP1.WIDTH": 17,
        "PCOMP2.WIDTH": 32,
        "PCAP.ARM": True,
        "SEQ1.TABLE": NEW_ROWS,
    }

    # a fresh process, its children at their defaults, loads it back
    fresh = zebra2(tmp_path / "fresh")
    shutil.copy(saved(tmp_path, "edited"), saved(tmp_path / "fresh", "edited"))

    async def again():
        await fresh.start()
        manager = await load(fresh, "edited")
        assert manager.current == "Ready"
        assert child(fresh, "PCOMP1").WIDTH.value == 17
        assert child(fresh, "PCOMP2").WIDTH.value == 32
        assert child(fresh, "PCAP").ARM.value is True
        assert rows(child(fresh, "SEQ1").TABLE.value) == NEW_ROWS
        assert rows(manager.exports.value) == rows(
            {"name": ("Arm", "Start"), "source": ("PCAP.START", "PCOMP1.START"),
             "description": ("Start the experiment", "")}
        )  # fmt: skip
        await fresh.stop()

    run(again)


def test_load_of_another_design_replaces_the_exports(tmp_path):
    process = zebra2(tmp_path)
    saved(tmp_path, "other").write_text(
        "parts.ExportPart:\n    name: Width\n    source: PCOMP1.WIDTH\n"
    )

    async def scenario():
        await process.start()
        manager = await load(process)
        await load(process, "other")
        assert manager.current == "Ready", manager.health.value
        assert "Width" in manager.block and "Start" not in manager.block
        assert "Arm" not in manager.block
        assert rows(manager.followers.value) == []
        assert manager.model_attr.value == ""
        assert not any(t.startswith("metaOf:") for t in manager.block.meta.tags)
        # PCOMP2.WIDTH is no longer fixed
        await process.put([f"{MRI}:PCOMP2", "WIDTH"], 3)
        await settle()
        assert manager.current == "Ready"
        await process.stop()

    run(scenario)


# ---- table edits go through Disabled; positions do not


def test_changing_the_exports_disables_with_the_new_parts(tmp_path):
    process = zebra2(tmp_path)

    async def scenario():
        await process.start()
        manager = await load(process)
        exports = rows(manager.exports.value)
        new = [*exports, {"name": "Width", "source": "PCOMP1.WIDTH",
                          "description": "Pulse width"}]  # fmt: skip
        await process.put([MRI, "exports"], new)
        assert manager.current == "Disabled"
        assert manager.modified.value is True
        assert manager.block.Width.meta.description == "Pulse width"
        assert rows(manager.exports.value) == new
        await process.post([MRI, "reset"])
        assert manager.current == "Ready"
        await process.put([MRI, "Width"], 12)
        assert child(process, "PCOMP1").WIDTH.value == 12
        # the fixed rows and the follower are still in force
        await process.put([f"{MRI}:PCOMP2", "WIDTH"], 1)
        await settle()
        assert manager.current == "Fault" and "PCOMP2.WIDTH" in manager.health.value
        await process.stop()

    run(scenario)


def test_exporting_a_fixed_attribute_unfixes_it(tmp_path):
    process = zebra2(tmp_path)

    async def scenario():
        await process.start()
        manager = await load(process)
        exports = rows(manager.exports.value)
        await process.put(
            [MRI, "exports"],
            [*exports, {"name": "Width2", "source": "PCOMP2.WIDTH", "description": ""}],
        )
        await process.post([MRI, "reset"])
        await process.put([MRI, "Width2"], 64)
        await settle()
        assert manager.current == "Ready"
        assert child(process, "PCOMP2").WIDTH.value == 64
        await process.stop()

    run(scenario)


def test_changing_the_followers_disables_with_the_new_parts(tmp_path):
    process = zebra2(tmp_path)

    async def scenario():
        await process.start()
        manager = await load(process)
        await process.put([MRI, "followers"], [])
        assert manager.current == "Disabled" and manager.modified.value is True
        await process.post([MRI, "reset"])
        await process.put([MRI, "Start"], 8.0)
        await settle()
        assert child(process, "PCOMP2").START.value != 8.0
        # PCOMP2.START is now free
        await process.put([f"{MRI}:PCOMP2", "START"], 1.0)
        await settle()
        assert manager.current == "Ready"
        await process.put(
            [MRI, "followers"], [{"name": "PCOMP2.START", "source": "Start"}]
        )
        assert manager.current == "Disabled"
        await process.post([MRI, "reset"])
        await settle()
        assert child(process, "PCOMP2").START.value == 8.0
        assert manager.current == "Ready"
        await process.stop()

    run(scenario)


def test_set_visible_disables_and_reset_brings_it_back(tmp_path):
    process = zebra2(tmp_path)

    async def scenario():
        await process.start()
        manager = await load(process)
        await process.post(
            [MRI, "set_visible"], {"block_name": "PCOMP2", "visible": True}
        )
        assert manager.current == "Disabled" and manager.modified.value is True
        assert manager.inactive == set()
        assert rows(manager.layout.value)[1]["visible"] is True
        await process.post([MRI, "reset"])
        assert manager.current == "Ready"
        await process.post(
            [MRI, "set_visible"], {"block_name": "PCAP", "visible": False}
        )
        assert manager.current == "Disabled" and manager.inactive == {"PCAP"}
        await process.post([MRI, "reset"])
        assert manager.current == "Ready"
        await process.stop()

    run(scenario)


def test_set_position_moves_without_disabling(tmp_path):
    process = zebra2(tmp_path)

    async def scenario():
        await process.start()
        manager = await load(process)
        states = []
        manager.state_listeners.append(lambda before, after: states.append(after))
        await process.post(
            [MRI, "set_position"], {"block_name": "PCAP", "x": 10, "y": 20.5}
        )
        assert states == [] and manager.current == "Ready"
        assert manager.modified.value is True
        pcap = rows(manager.layout.value)[2]
        assert (pcap["name"], pcap["x"], pcap["y"]) == ("PCAP", 10, 20.5)
        with pytest.raises(BadValueError, match="no child 'PCAP2'"):
            await process.post(
                [MRI, "set_position"], {"block_name": "PCAP2", "x": 1, "y": 2}
            )
        await process.post([MRI, "save"], {"design": "moved"})
        await process.stop()

    run(scenario)
    assert load_design(saved(tmp_path, "moved")).palette[2] == PalettePart(
        "PCAP", 10, 20, True
    )


# ---- bad designs: refused with a message naming the problem, nothing changes

BAD_DESIGNS = {
    "palette_child": (
        "parts.PalettePart:\n    name: PCOMP9\n    xcoord: 1\n    ycoord: 2\n"
        "    visible: Yes\n",
        ["bad.yaml:1:", "PCOMP9"],
    ),
    "export_child": (
        "parts.ExportPart:\n    name: Arm\n    source: PCAP2.START\n",
        ["'PCAP2.START'", "child 'PCAP2'"],
    ),
    "export_field": (
        "parts.ExportPart:\n    name: Arm\n    source: PCAP.STOP\n",
        ["'PCAP.STOP'", "field 'STOP'"],
    ),
    "follower_child": (
        "parts.ExportPart:\n    name: Start\n    source: PCOMP1.START\n"
        "parts.FollowerPart:\n    name: PCOMP3.START\n    source: Start\n",
        ["'PCOMP3.START'", "child 'PCOMP3'"],
    ),
    "follower_source": (
        "parts.FollowerPart:\n    name: PCOMP2.START\n    source: Begin\n",
        ["PCOMP2.START", "'Begin'"],
    ),
    "fixed_field": (
        "fixed.Int:\n    name: PCOMP2.HEIGHT\n    value: 3\n",
        ["'PCOMP2.HEIGHT'", "field 'HEIGHT'"],
    ),
    "fixed_column": (
        "fixed.Table:\n    name: SEQ1.TABLE\n    value:\n        - Phase3Time: 1\n",
        ["SEQ1.TABLE", "'Phase3Time'"],
    ),
    "fixed_type": (
        "fixed.Int:\n    name: SEQ1.TABLE\n    value: 3\n",
        ["SEQ1.TABLE", "table"],
    ),
    "fixed_read_only": (
        "fixed.String:\n    name: PCOMP1.health\n    value: fine\n",
        ["PCOMP1.health", "writeable"],
    ),
    "fixed_method": (
        "fixed.Int:\n    name: PCOMP1.reset\n    value: 1\n",
        ["PCOMP1.reset", "writeable attribute"],
    ),
    "follower_read_only": (
        "parts.FollowerPart:\n    name: PCOMP1.health\n    source: health\n",
        ["PCOMP1.health", "writeable"],
    ),
    "follower_type": (
        "parts.ExportPart:\n    name: Arm\n    source: PCAP.START\n"
        "parts.FollowerPart:\n    name: SEQ1.TABLE\n    source: Arm\n",
        ["SEQ1.TABLE", "Arm"],
    ),
    "follower_float_to_int": (
        "parts.ExportPart:\n    name: Start\n    source: PCOMP1.START\n"
        "parts.FollowerPart:\n    name: PCOMP1.WIDTH\n    source: Start\n",
        ["PCOMP1.WIDTH (int32) cannot follow Start (float64)"],
    ),
    "fixed_and_exported": (
        "parts.ExportPart:\n    name: Start\n    source: PCOMP1.START\n"
        "fixed.Float:\n    name: PCOMP1.START\n    value: 3\n",
        ["PCOMP1.START"],
    ),
    "syntax": (
        "fixed.Int:\n    name: PCOMP2.WIDTH\n    value: wide\n",
        ["bad.yaml:3:", "'value' must be an Int"],
    ),
    "two_problems": (
        "parts.ExportPart:\n    name: Arm\n    source: PCAP2.START\n"
        "fixed.Int:\n    name: PCOMP2.HEIGHT\n    value: 3\n",
        ["PCAP2", "PCOMP2.HEIGHT"],
    ),
}


@pytest.mark.parametrize("case", list(BAD_DESIGNS))
def test_a_bad_design_is_refused_and_changes_nothing(tmp_path, case):
    text, shown = BAD_DESIGNS[case]
    process = zebra2(tmp_path)
    saved(tmp_path, "bad").write_text(text)

    async def scenario():
        await process.start()
        await load(process)
        await process.put([MRI, "Start"], 2.5)
        await settle()
        before = snapshot(process)
        with pytest.raises(Exception) as info:
            await process.put([MRI, "design"], "bad")
        await settle()
        assert snapshot(process) == before
        for text in shown:
            assert text in str(info.value)
        # and still works
        await process.put([f"{MRI}:PCOMP2", "WIDTH"], 1)
        await settle()
        assert process.get_controller(MRI).current == "Fault"
        await process.stop()

    run(scenario)


def test_a_bad_design_before_any_is_loaded_changes_nothing(tmp_path):
    process = zebra2(tmp_path)
    saved(tmp_path, "bad").write_text(BAD_DESIGNS["export_child"][0])

    async def scenario():
        await process.start()
        before = snapshot(process)
        with pytest.raises(BadValueError):
            await process.post([MRI, "load"], {"design": "bad"})
        assert snapshot(process) == before
        await process.stop()

    run(scenario)


def test_a_table_edit_naming_a_missing_attribute_changes_nothing(tmp_path):
    process = zebra2(tmp_path)

    async def scenario():
        await process.start()
        manager = await load(process)
        before = snapshot(process)
        bad = [{"name": "X", "source": "PCAP.STOP", "description": ""}]
        with pytest.raises(BadValueError, match="'PCAP.STOP'"):
            await process.put([MRI, "exports"], rows(manager.exports.value) + bad)
        with pytest.raises(BadValueError, match="PCOMP7"):
            await process.put(
                [MRI, "followers"], [{"name": "PCOMP7.START", "source": "Start"}]
            )
        assert snapshot(process) == before
        await process.stop()

    run(scenario)


# ---- templates, design names and the design choices


def test_a_template_loads_but_is_not_overwritten(tmp_path):
    process = zebra2(tmp_path)
    templates = tmp_path / "templates"
    templates.mkdir()
    shutil.copy(EXAMPLE, templates / "shipped.yaml")
    manager = process.get_controller(MRI)
    manager.template_dirs = [templates]

    async def scenario():
        await process.start()
        assert "shipped" in manager.design.meta.choices
        await load(process, "shipped")
        assert manager.design.value == "shipped"
        assert child(process, "PCOMP2").WIDTH.value == 32
        with pytest.raises(BadValueError, match="'shipped' is a read-only template"):
            await process.post([MRI, "save"])
        with pytest.raises(BadValueError, match="read-only template"):
            await process.post([MRI, "save"], {"design": "shipped"})
        assert manager.current == "Ready" and manager.design.value == "shipped"
        await process.post([MRI, "save"], {"design": "mine"})
        assert manager.design.value == "mine"
        await process.stop()

    run(scenario)
    assert (templates / "shipped.yaml").read_text() == EXAMPLE.read_text()
    assert saved(tmp_path, "mine").exists()
    assert sorted(p.name for p in templates.iterdir()) == ["shipped.yaml"]


def test_design_choices_are_the_saved_designs(tmp_path):
    process = zebra2(tmp_path)
    manager = process.get_controller(MRI)

    async def scenario():
        await process.start()
        assert manager.design.meta.choices == ("", "example")
        await load(process)
        await process.post([MRI, "save"], {"design": "b-2.v1"})
        assert manager.design.meta.choices == ("", "b-2.v1", "example")
        # one saved by another hand can be loaded
        shutil.copy(EXAMPLE, saved(tmp_path, "copied"))
        await load(process, "copied")
        assert manager.design.value == "copied"
        assert "copied" in manager.design.meta.choices
        with pytest.raises(BadValueError):
            await process.put([MRI, "design"], "nothere")
        await process.stop()

    run(scenario)


@pytest.mark.parametrize("name", ["../escape", "a/b", "/abs", "..", ".hidden", "a\\b"])
def test_design_names_with_path_separators_are_refused(tmp_path, name):
    process = zebra2(tmp_path)
    manager = process.get_controller(MRI)

    async def scenario():
        await process.start()
        await load(process)
        before = snapshot(process)
        with pytest.raises(BadValueError, match="not a design name"):
            await process.post([MRI, "save"], {"design": name})
        with pytest.raises(BadValueError):
            await process.post([MRI, "load"], {"design": name})
        assert snapshot(process) == before
        assert manager.current == "Ready"
        await process.stop()

    run(scenario)
    files = sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*"))
    assert files == ["designs", "designs/BL18I_Z1", "designs/BL18I_Z1/example.yaml"]


def test_save_and_load_are_refused_outside_ready(tmp_path):
    process = zebra2(tmp_path)

    async def scenario():
        await process.start()
        await load(process)
        await process.put([f"{MRI}:PCOMP2", "WIDTH"], 1)
        await settle()
        with pytest.raises(NotAllowedError):
            await process.post([MRI, "save"], {"design": "x"})
        with pytest.raises(NotAllowedError):
            await process.put([MRI, "design"], "example")
        await process.stop()

    run(scenario)
    assert not saved(tmp_path, "x").exists()


# ---- malcolm check on designs


def test_malcolm_check_passes_the_example(capsys):
    from malcolm.cli import main

    assert main(["check", str(EXAMPLE)]) == 0
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err


def test_malcolm_check_gives_file_line_of_a_broken_design(tmp_path, capsys):
    from malcolm.cli import main

    bad = tmp_path / "broken.yaml"
    bad.write_text(
        EXAMPLE.read_text()
        .replace("value: 32", "value: wide")
        .replace("source: Start", "sorce: Start")
    )
    assert main(["check", str(bad)]) == 1
    out, _ = capsys.readouterr()
    lines = out.splitlines()
    assert f"{bad}:33: parts.FollowerPart: unknown key 'sorce'" in "\n".join(lines)
    assert any(line.startswith(f"{bad}:37: fixed.Int: 'value' must be an Int")
               for line in lines)  # fmt: skip


def test_a_design_loads_the_same_whatever_was_loaded_before(tmp_path):
    process = zebra2(tmp_path)

    async def scenario():
        await process.start()
        manager = await load(process)
        first = manager.layout.value
        # SEQ1 is not in the example's palette
        await process.post(
            [MRI, "set_position"], {"block_name": "SEQ1", "x": 5, "y": 6}
        )
        await process.post(
            [MRI, "set_visible"], {"block_name": "SEQ1", "visible": False}
        )
        await process.post([MRI, "reset"])
        assert manager.inactive == {"PCOMP2", "SEQ1"}
        await load(process)
        assert manager.layout.value == first
        assert manager.inactive == {"PCOMP2"}
        await process.stop()

    run(scenario)


def test_a_saved_design_is_readable_by_others(tmp_path):
    process = zebra2(tmp_path)
    umask = os.umask(0o022)

    async def scenario():
        await process.start()
        await load(process)
        await process.post([MRI, "save"], {"design": "first"})
        await process.post([MRI, "save"], {"design": "shared"})
        saved(tmp_path, "shared").chmod(0o640)
        await process.post([MRI, "save"], {"design": "shared"})
        await process.stop()

    try:
        run(scenario)
    finally:
        os.umask(umask)
    # an existing design keeps its mode; a new one gets 0666 less the umask
    assert stat.S_IMODE(saved(tmp_path, "shared").stat().st_mode) == 0o640
    assert stat.S_IMODE(saved(tmp_path, "first").stat().st_mode) == 0o644
    leftovers = [p.name for p in saved(tmp_path, "x").parent.iterdir()]
    assert sorted(leftovers) == ["example.yaml", "first.yaml", "shared.yaml"]


def test_an_export_named_after_a_configure_argument_is_refused(tmp_path):
    process = runnable_zebra2(tmp_path)
    saved(tmp_path, "gen").write_text(
        "parts.ExportPart:\n    name: generator\n    source: PCOMP1.START\n"
    )

    async def scenario():
        await process.start()
        await load(process)
        before = snapshot(process)
        with pytest.raises(BadValueError, match="'generator' is not a free field"):
            await process.put([MRI, "design"], "gen")
        assert snapshot(process) == before
        takes = process.get_controller(MRI).block.configure.meta.takes.elements
        assert list(takes) == ["generator", "axesToMove", "breakpoints", "Arm", "Start"]
        await process.stop()

    run(scenario)

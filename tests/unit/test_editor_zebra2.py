"""The Zebra2 example: the design document's Manager over soft children.

Every test copies the repository's ``designs/`` example into ``tmp_path``
and points the process there: nothing is written into the repository.
"""

from __future__ import annotations

import asyncio
import shutil
from pathlib import Path

import pytest

import malcolm
from malcolm.config.build import build_definition, build_process
from malcolm.config.errors import ConfigError
from malcolm.controllers.manager import ManagerController
from malcolm.core import NumberMeta, Process, TableMeta
from malcolm.editor.store import DesignStore
from malcolm.parts.base import ChildPart
from malcolm.parts.soft import CATablePart

from .scans import compound, run

ROOT = Path(__file__).resolve().parents[2]
ZEBRA2 = Path(malcolm.__file__).parent / "blocks" / "zebra2"
EXAMPLE = ROOT / "designs" / "BL18I_Z1" / "example.yaml"
FIXTURE = Path(__file__).parent / "config_fixtures" / "designs" / "PositionBased.yaml"
MRI = "BL18I:Z1"
CHILDREN = ("PCOMP1", "PCOMP2", "PCAP", "SEQ1")
TABLE_ROWS = [
    {"Phase1Time": 32, "Phase2Time": 45, "NRepeats": 3},
    {"Phase1Time": 3, "Phase2Time": 5, "NRepeats": 1},
]


# ---- helpers (the other test_editor_* modules use them too)


def designs_in(tmp_path: Path) -> Path:
    """A designs directory in tmp_path holding a copy of the example."""
    designs = tmp_path / "designs"
    (designs / "BL18I_Z1").mkdir(parents=True, exist_ok=True)
    shutil.copy(EXAMPLE, designs / "BL18I_Z1" / "example.yaml")
    return designs


def zebra2(tmp_path: Path, name: str = "z") -> Process:
    """The example process, its designs in tmp_path (not started)."""
    process = Process(name, designs_dir=str(designs_in(tmp_path)))
    return build_process(ZEBRA2 / "process.yaml", process=process)


def child(process: Process, name: str):
    return process.get_block(f"{MRI}:{name}")


def rows(table) -> list[dict]:
    columns = list(table)
    n = len(table[columns[0]]) if columns else 0
    return [{c: table[c][i] for c in columns} for i in range(n)]


async def settle() -> None:
    """Let subscriptions and background follower writes finish."""
    for _ in range(5):
        await asyncio.sleep(0)
    await asyncio.sleep(0.01)


async def load(process: Process, design: str = "example") -> ManagerController:
    await process.put([MRI, "design"], design)
    await settle()
    return process.get_controller(MRI)


def snapshot(process: Process) -> dict:
    """Everything a failed load must leave as it was."""
    manager = process.get_controller(MRI)
    return {
        "state": manager.current,
        "health": manager.health.value,
        "fields": list(manager.block),
        "design": manager.design.value,
        "modified": manager.modified.value,
        "layout": manager.layout.value,
        "exports": manager.exports.value,
        "followers": manager.followers.value,
        "model": manager.model_attr.value,
        "tags": manager.block.meta.tags,
        "parts": list(manager.parts),
        "inactive": set(manager.inactive),
        "children": {
            n: {k: a.value for k, a in child(process, n).attributes.items()}
            for n in CHILDREN
        },
    }


# ---- the definitions


def test_the_process_makes_the_manager_and_its_four_children():
    process = build_process(ZEBRA2 / "process.yaml")
    assert process.mris == [f"{MRI}:{n}" for n in CHILDREN] + [MRI]
    manager = process.get_controller(MRI)
    assert type(manager) is ManagerController
    assert manager.children == {n: f"{MRI}:{n}" for n in CHILDREN}
    assert all(isinstance(manager.parts[n], ChildPart) for n in CHILDREN)
    # the fields the design document uses, all writeable
    fields = {n: [k for k in child(process, n).attributes] for n in CHILDREN}
    assert fields == {
        "PCOMP1": ["health", "state", "START", "WIDTH"],
        "PCOMP2": ["health", "state", "START", "WIDTH"],
        "PCAP": ["health", "state", "ARM", "START"],
        "SEQ1": ["health", "state", "TABLE"],
    }
    table = child(process, "SEQ1").TABLE
    assert isinstance(table.meta, TableMeta) and table.meta.writeable
    assert list(table.meta.elements) == ["Phase1Time", "Phase2Time", "NRepeats"]
    assert all(m.dtype == "int32" for m in table.meta.elements.values())
    assert child(process, "PCOMP2").WIDTH.meta.dtype == "int32"
    parts = process.get_controller(f"{MRI}:PCOMP1").parts
    assert parts["WIDTH"].pv == "BL18I-EA-ZEBRA-01:PCOMP1:WIDTH"
    assert parts["WIDTH"].rbv == "BL18I-EA-ZEBRA-01:PCOMP1:WIDTH_RBV"


def test_designs_dir_is_an_init_parameter(tmp_path):
    process = build_definition("zebra2.Zebra2", {"designs_dir": str(tmp_path)}, MRI)
    manager = process.get_controller(MRI)

    async def scenario():
        await process.start()
        assert manager.store.dir == tmp_path / "BL18I_Z1"
        await process.stop()

    run(scenario)


def test_without_it_the_process_designs_dir_is_used(tmp_path):
    process = zebra2(tmp_path)
    manager = process.get_controller(MRI)
    assert manager.designs_dir is None

    async def scenario():
        await process.start()
        assert manager.store.dir == tmp_path / "designs" / "BL18I_Z1"
        await process.stop()

    run(scenario)


def test_the_example_is_where_the_manager_looks_and_is_the_documents():
    store = DesignStore(MRI, ROOT / "designs")
    assert store.path("example") == EXAMPLE
    # verbatim from the design document (the config tests' fixture is too)
    assert EXAMPLE.read_text() == FIXTURE.read_text()


def test_the_initial_design_loads_at_start(tmp_path):
    process = build_definition(
        "zebra2.Zebra2",
        {"designs_dir": str(designs_in(tmp_path)), "design": "example"},
        MRI,
    )

    async def scenario():
        await process.start()
        manager = process.get_controller(MRI)
        assert (manager.current, manager.design.value) == ("Ready", "example")
        assert child(process, "PCOMP2").WIDTH.value == 32
        await process.stop()

    run(scenario)


def test_ca_table_checks_its_columns():
    part = CATablePart("T", pv="P", writeable=True, columns={"a": "Long", "b": "Bool"})
    assert part.meta.validate([{"a": 1, "b": True}]) == {"a": (1,), "b": (True,)}
    assert "widget:table" in part.meta.tags
    with pytest.raises(ValueError, match="columns must map"):
        CATablePart("T", pv="P", columns=["a"])
    with pytest.raises(ValueError, match="type 'Blob' is not one of Long"):
        CATablePart("T", pv="P", columns={"a": "Blob"})
    with pytest.raises(ValueError, match="not an identifier"):
        CATablePart("T", pv="P", columns={"a b": "Long"})


def test_a_bad_ca_table_in_a_definition_is_a_file_line_error(tmp_path):
    path = tmp_path / "T.yaml"
    path.write_text(
        "ca.Table:\n    name: T\n    pv: P\n    columns:\n        a: Blob\n"
    )
    with pytest.raises(ConfigError) as info:
        build_definition(path, {}, "T")
    assert str(info.value).startswith(f"{path}:1: ca.Table: column a: type 'Blob'")


# ---- the example design, as the document describes it


def test_the_example_loads(tmp_path):
    process = zebra2(tmp_path)

    async def scenario():
        await process.start()
        manager = await load(process)
        block = manager.block
        assert manager.current == "Ready" and manager.health.value == "OK"
        assert (manager.design.value, manager.modified.value) == ("example", False)
        assert rows(manager.exports.value) == [
            {"name": "Arm", "source": "PCAP.START",
             "description": "Start the experiment"},
            {"name": "Start", "source": "PCOMP1.START", "description": ""},
        ]  # fmt: skip
        assert rows(manager.followers.value) == [
            {"name": "PCOMP2.START", "source": "Start"}
        ]
        assert rows(manager.layout.value) == [
            {"name": "PCOMP1", "mri": f"{MRI}:PCOMP1", "x": 12, "y": 15,
             "visible": True},
            {"name": "PCOMP2", "mri": f"{MRI}:PCOMP2", "x": 0, "y": 0,
             "visible": False},
            {"name": "PCAP", "mri": f"{MRI}:PCAP", "x": 200, "y": 230,
             "visible": True},
            # not in the design's palette: where it was
            {"name": "SEQ1", "mri": f"{MRI}:SEQ1", "x": 0, "y": 0, "visible": True},
        ]  # fmt: skip
        assert manager.inactive == {"PCOMP2"}
        # the exports are fields of the manager, described as the design says
        assert block.Arm.meta.description == "Start the experiment"
        assert (
            block.Start.meta.description
            == child(process, "PCOMP1").START.meta.description
        )
        # the fixed values are written
        assert child(process, "PCOMP2").WIDTH.value == 32
        assert rows(child(process, "SEQ1").TABLE.value) == TABLE_ROWS
        # the model
        assert manager.model_attr.value == "PositionBased"
        assert "metaOf:PositionBased" in block.meta.tags
        await process.stop()

    run(scenario)


def test_the_model_is_the_block_meta_tag(tmp_path):
    process = zebra2(tmp_path)

    async def scenario():
        await process.start()
        manager = process.get_controller(MRI)
        assert manager.model_attr.value == ""
        assert not any(t.startswith("metaOf:") for t in manager.block.meta.tags)
        tags = []
        process.subscribe([MRI, "meta", "tags"], tags.append, delta=False)
        await load(process)
        assert list(tags[-1]) == ["metaOf:PositionBased"]
        assert process.get([MRI, "model", "value"]) == "PositionBased"
        await process.stop()

    run(scenario)


def test_fixed_values_are_written_on_load(tmp_path):
    process = zebra2(tmp_path)

    async def scenario():
        await process.start()
        await process.put([f"{MRI}:PCOMP2", "WIDTH"], 7)
        await process.put([f"{MRI}:SEQ1", "TABLE"], [{"Phase1Time": 1}])
        await load(process)
        assert child(process, "PCOMP2").WIDTH.value == 32
        assert rows(child(process, "SEQ1").TABLE.value) == TABLE_ROWS
        await process.stop()

    run(scenario)


def test_exports_mirror_their_children_both_ways(tmp_path):
    process = zebra2(tmp_path)

    async def scenario():
        await process.start()
        manager = await load(process)
        block = manager.block
        # the child changes: the export changes
        await process.put([f"{MRI}:PCAP", "START"], True)
        await process.put([f"{MRI}:PCOMP1", "START"], 1.5)
        await settle()
        assert block.Arm.value is True and block.Start.value == 1.5
        # a write to the export goes to the child
        await process.put([MRI, "Arm"], False)
        await process.put([MRI, "Start"], 4.25)
        await settle()
        assert child(process, "PCAP").START.value is False
        assert child(process, "PCOMP1").START.value == 4.25
        assert block.Arm.meta.writeable and block.Start.meta.writeable
        assert manager.current == "Ready"
        await process.stop()

    run(scenario)


def test_the_follower_follows_start(tmp_path):
    process = zebra2(tmp_path)

    async def scenario():
        await process.start()
        manager = await load(process)
        assert child(process, "PCOMP2").START.value == manager.block.Start.value
        await process.put([MRI, "Start"], 2.5)
        await settle()
        assert child(process, "PCOMP2").START.value == 2.5
        # a change of the export's child counts as a change of Start
        await process.put([f"{MRI}:PCOMP1", "START"], 3.5)
        await settle()
        assert child(process, "PCOMP2").START.value == 3.5
        assert manager.current == "Ready" and manager.health.value == "OK"
        await process.stop()

    run(scenario)


def test_the_follower_changed_by_another_hand_is_a_fault(tmp_path):
    process = zebra2(tmp_path)

    async def scenario():
        await process.start()
        manager = await load(process)
        await process.put([MRI, "Start"], 2.5)
        await settle()
        await process.put([f"{MRI}:PCOMP2", "START"], 7)
        await settle()
        assert manager.current == "Fault"
        health = manager.health.value
        assert "PCOMP2.START" in health and "Start" in health
        assert "expected 2.5" in health and "7.0" in health
        # reset writes the followed value back
        await process.post([MRI, "reset"])
        await settle()
        assert manager.current == "Ready" and manager.health.value == "OK"
        assert child(process, "PCOMP2").START.value == 2.5
        await process.stop()

    run(scenario)


@pytest.mark.parametrize(
    ("name", "field", "value", "shown"),
    [
        ("PCOMP2", "WIDTH", 5, ["PCOMP2.WIDTH", "32", "5"]),
        ("SEQ1", "TABLE", [{"Phase1Time": 1, "Phase2Time": 2, "NRepeats": 3}],
         ["SEQ1.TABLE", "(32, 3)", "(1,)"]),
    ],
)  # fmt: skip
def test_a_fixed_value_that_drifts_is_a_fault_and_reset_writes_it_back(
    tmp_path, name, field, value, shown
):
    process = zebra2(tmp_path)

    async def scenario():
        await process.start()
        manager = await load(process)
        await process.put([f"{MRI}:{name}", field], value)
        await settle()
        assert manager.current == "Fault"
        for text in shown:
            assert text in manager.health.value
        await process.post([MRI, "reset"])
        await settle()
        assert manager.current == "Ready" and manager.health.value == "OK"
        assert child(process, "PCOMP2").WIDTH.value == 32
        assert rows(child(process, "SEQ1").TABLE.value) == TABLE_ROWS
        await process.stop()

    run(scenario)


def test_attributes_the_design_does_not_mention_are_free(tmp_path):
    process = zebra2(tmp_path)

    async def scenario():
        await process.start()
        manager = await load(process)
        await process.put([f"{MRI}:PCOMP1", "WIDTH"], 9)
        await process.put([f"{MRI}:PCAP", "ARM"], True)
        await settle()
        assert manager.current == "Ready"
        await process.stop()

    run(scenario)


# ---- on a runnable manager, writeable exports are configure() arguments


def runnable_zebra2(tmp_path: Path) -> Process:
    blocks = tmp_path / "blocks" / "lab"
    blocks.mkdir(parents=True)
    text = (ZEBRA2 / "Zebra2.yaml").read_text()
    text = text.replace(
        "controller.ManagerController:", "controller.RunnableController:"
    )
    (blocks / "RunnableZebra2.yaml").write_text(text)
    process = Process("rz", designs_dir=str(designs_in(tmp_path)))
    return build_definition(
        "lab.RunnableZebra2", {}, MRI, [tmp_path / "blocks"], process=process
    )


def test_a_runnable_manager_takes_writeable_exports_in_configure(tmp_path):
    process = runnable_zebra2(tmp_path)

    async def scenario():
        await process.start()
        manager = await load(process)
        takes = manager.block.configure.meta.takes.elements
        assert {"Arm", "Start"} <= set(takes)
        assert isinstance(takes["Start"], NumberMeta)
        await process.post(
            [MRI, "configure"], {"generator": compound(("x", 2)), "Start": 6.5,
                                  "Arm": True}
        )  # fmt: skip
        await settle()
        assert manager.current == "Armed"
        assert child(process, "PCOMP1").START.value == 6.5
        assert child(process, "PCOMP2").START.value == 6.5  # it follows Start
        assert child(process, "PCAP").START.value is True
        # an export left out of configure() is not written
        await process.post([MRI, "reset"])
        await process.post([MRI, "configure"], {"generator": compound(("x", 2))})
        await settle()
        assert child(process, "PCOMP1").START.value == 6.5
        await process.stop()

    run(scenario)


# ---- invisible children: their parts' hooks do not run


class RecordingChildPart(ChildPart):
    from malcolm.fsm import Stateful

    calls: list[str] = []

    @Stateful.Reset
    async def reset(self, task, device):
        self.calls.append(self.name)


def test_hooks_of_invisible_children_do_not_run(tmp_path):
    process = Process("h", designs_dir=str(designs_in(tmp_path)))
    for name, kind in zip(CHILDREN, ("PCOMP", "PCOMP", "PCAP", "SEQ")):
        build_definition(
            f"zebra2.{kind}", {"prefix": name}, f"{MRI}:{name}", process=process
        )
    RecordingChildPart.calls = []
    parts = [RecordingChildPart(n, f"{MRI}:{n}") for n in CHILDREN]
    manager = ManagerController(MRI, parts)
    process.add_controller(manager)

    async def scenario():
        await process.start()
        assert sorted(RecordingChildPart.calls) == sorted(CHILDREN)
        await load(process)  # PCOMP2 is not visible
        RecordingChildPart.calls.clear()
        await process.post([MRI, "disable"])
        await process.post([MRI, "reset"])
        assert sorted(RecordingChildPart.calls) == ["PCAP", "PCOMP1", "SEQ1"]
        await process.post([MRI, "set_visible"], {"block_name": "PCOMP2",
                                                  "visible": True})  # fmt: skip
        RecordingChildPart.calls.clear()
        await process.post([MRI, "reset"])
        assert sorted(RecordingChildPart.calls) == sorted(CHILDREN)
        await process.stop()

    run(scenario)

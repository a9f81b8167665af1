"""The manager's ``fixed`` table: shown live, edited like ``exports``.

Rows are ``name`` (CHILD.ATTRIBUTE) and ``value`` (JSON text). Before this
table existed a manager had no ``fixed`` attribute at all.
"""

from __future__ import annotations

import json

import pytest

from malcolm.core import BadValueError, NotAllowedError
from malcolm.parts.design import load_design

from .scans import run
from .test_editor_zebra2 import EXAMPLE, MRI, child, load, rows, settle, zebra2

SEQ_ROWS = [
    {"Phase1Time": 32, "Phase2Time": 45, "NRepeats": 1},
    {"Phase1Time": 1, "Phase2Time": 2, "NRepeats": 3},
]


def fixed_rows(manager) -> dict[str, object]:
    """The fixed table as ``{name: decoded value}``."""
    return {r["name"]: json.loads(r["value"]) for r in rows(manager.fixed.value)}


def test_the_fixed_table_shows_the_loaded_designs_rows(tmp_path):
    process = zebra2(tmp_path)

    async def scenario():
        await process.start()
        manager = await process_manager(process)
        assert rows(manager.fixed.value) == []
        await load(process)
        # the example's own fixed records, in its order
        assert fixed_rows(manager) == {
            r.name: r.value for r in load_design(EXAMPLE).fixed
        }
        assert fixed_rows(manager)["PCOMP2.WIDTH"] == 32
        assert manager.block.meta.fields.count("fixed") == 1
        await process.stop()

    run(scenario)


async def process_manager(process):
    return process.get_controller(MRI)


def test_a_put_of_fixed_disables_then_reset_writes_the_values(tmp_path):
    process = zebra2(tmp_path)

    async def scenario():
        await process.start()
        manager = await load(process)
        new = [
            {"name": "PCOMP2.WIDTH", "value": "7"},
            {"name": "PCOMP1.WIDTH", "value": "12"},
            {"name": "SEQ1.TABLE", "value": json.dumps(SEQ_ROWS)},
        ]
        await process.put([MRI, "fixed"], new)
        assert manager.current == "Disabled"
        assert manager.modified.value is True
        assert fixed_rows(manager) == {
            "PCOMP2.WIDTH": 7,
            "PCOMP1.WIDTH": 12,
            "SEQ1.TABLE": SEQ_ROWS,
        }
        await process.post([MRI, "reset"])
        assert manager.current == "Ready"
        assert child(process, "PCOMP2").WIDTH.value == 7
        assert child(process, "PCOMP1").WIDTH.value == 12
        assert list(child(process, "SEQ1").TABLE.value["NRepeats"]) == [1, 3]
        # the new row is held: anyone else's change is drift
        await process.put([f"{MRI}:PCOMP1", "WIDTH"], 3)
        await settle()
        assert manager.current == "Fault"
        assert "PCOMP1.WIDTH is fixed at 12" in manager.health.value
        await process.stop()

    run(scenario)


def test_a_row_dropped_from_fixed_is_no_longer_held(tmp_path):
    process = zebra2(tmp_path)

    async def scenario():
        await process.start()
        manager = await load(process)
        keep = [r for r in rows(manager.fixed.value) if r["name"] != "PCOMP2.WIDTH"]
        await process.put([MRI, "fixed"], keep)
        await process.post([MRI, "reset"])
        await process.put([f"{MRI}:PCOMP2", "WIDTH"], 5)
        await settle()
        assert manager.current == "Ready"
        assert list(fixed_rows(manager)) == ["SEQ1.TABLE"]
        await process.stop()

    run(scenario)


BAD = [
    ({"name": "NOPE.WIDTH", "value": "1"}, ["row 2 (NOPE.WIDTH)", "NOPE"]),
    ({"name": "PCOMP1.NOPE", "value": "1"}, ["row 2 (PCOMP1.NOPE)", "NOPE"]),
    ({"name": "PCOMP1.WIDTH", "value": "{oops"}, ["row 2 (PCOMP1.WIDTH)", "JSON"]),
    ({"name": "PCOMP1.WIDTH", "value": '"wide"'}, ["fixed PCOMP1.WIDTH", "wide"]),
    ({"name": "PCAP.START", "value": "true"}, ["PCAP.START is fixed, and also"]),
    ({"name": "PCOMP2.START", "value": "1.0"}, ["PCOMP2.START is fixed, and also"]),
    ({"name": "PCOMP2.WIDTH", "value": "9"}, ["PCOMP2.WIDTH has two fixed rows"]),
]


@pytest.mark.parametrize("bad,words", BAD, ids=[b["name"] for b, _ in BAD])
def test_a_bad_fixed_row_is_refused_naming_it_and_nothing_changes(tmp_path, bad, words):
    process = zebra2(tmp_path)

    async def scenario():
        await process.start()
        manager = await load(process)
        before = rows(manager.fixed.value)
        with pytest.raises(BadValueError) as e:
            await process.put([MRI, "fixed"], [*before, bad])
        for word in words:
            assert word in str(e.value)
        assert manager.current == "Ready"
        assert manager.modified.value is False
        assert rows(manager.fixed.value) == before
        assert child(process, "PCOMP2").WIDTH.value == 32
        await process.stop()

    run(scenario)


def test_fixed_is_put_in_ready_only(tmp_path):
    process = zebra2(tmp_path)

    async def scenario():
        await process.start()
        manager = await load(process)
        await process.post([MRI, "disable"])
        with pytest.raises(NotAllowedError):
            await process.put([MRI, "fixed"], [])
        assert len(rows(manager.fixed.value)) == 2
        await process.stop()

    run(scenario)


def test_edit_fixed_save_load_gives_the_same_rows(tmp_path):
    process = zebra2(tmp_path)

    async def scenario():
        await process.start()
        manager = await load(process)
        # a save fixes every writeable attribute not exported or followed
        await process.post([MRI, "save"], {"design": "all"})
        table = rows(manager.fixed.value)
        assert {r["name"] for r in table} == {
            "PCOMP1.WIDTH", "PCOMP2.WIDTH", "PCAP.ARM", "SEQ1.TABLE"
        }  # fmt: skip
        edited = [
            {**r, "value": "17"} if r["name"] == "PCOMP1.WIDTH" else r for r in table
        ]
        await process.put([MRI, "fixed"], edited)
        await process.post([MRI, "reset"])
        await process.post([MRI, "save"], {"design": "edited"})
        saved = load_design(tmp_path / "designs" / "BL18I_Z1" / "edited.yaml")
        assert {r.name: r.value for r in saved.fixed} == {
            r["name"]: json.loads(r["value"]) for r in edited
        }
        await process.put([f"{MRI}:PCOMP1", "WIDTH"], 17)  # already 17: no drift
        await load(process, "all")
        assert fixed_rows(manager)["PCOMP1.WIDTH"] == 0
        await load(process, "edited")
        assert rows(manager.fixed.value) == edited
        assert child(process, "PCOMP1").WIDTH.value == 17
        assert manager.modified.value is False
        await process.stop()

    run(scenario)


def test_exporting_a_fixed_attribute_drops_its_fixed_row(tmp_path):
    process = zebra2(tmp_path)

    async def scenario():
        await process.start()
        manager = await load(process)
        exports = rows(manager.exports.value)
        await process.put(
            [MRI, "exports"],
            [*exports, {"name": "Width2", "source": "PCOMP2.WIDTH", "description": ""}],
        )
        assert list(fixed_rows(manager)) == ["SEQ1.TABLE"]
        await process.stop()

    run(scenario)


def test_reset_writes_the_fixed_value_back(tmp_path):
    process = zebra2(tmp_path)

    async def scenario():
        await process.start()
        manager = await load(process)
        await process.put([f"{MRI}:PCOMP2", "WIDTH"], 1)
        await settle()
        assert manager.current == "Fault"
        await process.post([MRI, "reset"])
        assert manager.current == "Ready"
        assert child(process, "PCOMP2").WIDTH.value == 32
        assert fixed_rows(manager)["PCOMP2.WIDTH"] == 32
        await process.stop()

    run(scenario)

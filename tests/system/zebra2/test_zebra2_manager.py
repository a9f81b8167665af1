"""A process with a zebra2.Manager on the simulated box (a subprocess).

Issue 11's acceptance: every tier-2 block and field is a child attribute
with the right meta; another client's write shows up within two polls; bad
puts return the box's error and change nothing; the BL18I_Z1 design drives
the box; a followed field written behind the manager's back faults it;
killing the box gives INVALID alarms and health, restarting it recovers.
"""

from __future__ import annotations

import asyncio
import json
import shutil
from pathlib import Path

import pytest

from malcolm.config.build import build_definition
from malcolm.core import (
    AlarmSeverity,
    BooleanMeta,
    ChoiceMeta,
    Method,
    NumberMeta,
    Process,
    StringMeta,
    TableMeta,
)
from malcolm.io.zebra2 import Zebra2Error

from .conftest import ROOT, RawClient, SimBox

TIER2 = ROOT / "malcolm" / "sim" / "zebra2" / "data" / "introspection-tier2.json"
DESIGN = ROOT / "designs" / "zebra2-tier2" / "BL18I_Z1" / "example.yaml"
MRI = "BL18I:Z1"
POLL = 0.05


def manager_process(sim: SimBox, tmp_path: Path, poll: float = POLL) -> Process:
    designs = tmp_path / "designs" / "BL18I_Z1"
    designs.mkdir(parents=True, exist_ok=True)
    shutil.copy(DESIGN, designs / "example.yaml")
    process = Process("z2", designs_dir=str(tmp_path / "designs"))
    params = {
        "host": sim.host,
        "control_port": sim.control_port,
        "data_port": sim.data_port,
        "poll_period": poll,
    }
    return build_definition("zebra2.Manager", params, MRI, process=process)


def run(sim: SimBox, tmp_path: Path, body, poll: float = POLL):
    async def main():
        process = manager_process(sim, tmp_path, poll)
        await process.start()
        raw = await RawClient.open(sim)
        try:
            return await body(process, raw)
        finally:
            await raw.close()
            await process.stop()

    return asyncio.run(main())


async def until(check, timeout: float = 10.0, what: str = "") -> None:
    """Wait (polling) until ``check()`` is true; fail after ``timeout``."""
    for _ in range(int(timeout / 0.01)):
        if check():
            return
        await asyncio.sleep(0.01)
    raise AssertionError(f"not within {timeout} s: {what}")


def child(process: Process, name: str):
    return process.get_block(f"{MRI}:{name}")


def test_every_recorded_block_and_field_is_a_child_attribute_with_its_meta(
    sim, tmp_path
):
    recorded = json.loads(TIER2.read_text())["block_details"]

    async def body(process, raw):
        manager = process.get_block(MRI)
        assert manager.state.value == "Ready", manager.health.value
        expected = []
        for block, details in recorded.items():
            n = details["count"]
            expected += [block] if n == 1 else [f"{block}{i}" for i in range(1, n + 1)]
        assert sorted(process.get_controller(MRI).children) == sorted(expected)
        # the palette has them all (the Editor's layout)
        assert sorted(manager.layout.value["name"]) == sorted(expected)
        assert manager.layout.value["mri"][0] == f"{MRI}:{expected[0]}"
        kinds = {
            "uint": NumberMeta,
            "int": NumberMeta,
            "time": NumberMeta,
            "bit": BooleanMeta,
            "enum": ChoiceMeta,
            "lut": StringMeta,
            "bit_out": BooleanMeta,
            "pos_out": NumberMeta,
            "bit_mux": ChoiceMeta,
            "pos_mux": ChoiceMeta,
            "table": TableMeta,
        }
        dtypes = {
            "uint": "uint32",
            "int": "int32",
            "time": "float64",
            "pos_out": "int32",
        }
        for block, details in recorded.items():
            name = block if details["count"] == 1 else f"{block}1"
            b = child(process, name)
            assert b.state.value == "Ready"
            for f in details["fields"]:
                ftype, sub = f["type"], f["subtype"]
                kind = sub if ftype in ("param", "read", "write") else ftype
                where = f"{name}.{f['name']} ({ftype} {sub})"
                if ftype == "write":
                    assert isinstance(b[f["name"]], Method), where
                    continue
                if ftype == "ext_out":
                    meta = b[f"{f['name']}_CAPTURE"].meta
                    assert isinstance(meta, ChoiceMeta), where
                    labels = f["attributes"]["CAPTURE"]["enums"]["values"]
                    assert list(meta.choices) == labels, where
                    continue
                meta = b[f["name"]].meta
                assert isinstance(meta, kinds[kind]), where
                assert meta.writeable == (
                    ftype in ("param", "time", "bit_mux", "pos_mux", "table")
                ), where
                if kind in dtypes:
                    assert meta.dtype == dtypes[kind], where
                labels = (f.get("enums") or {}).get("values")
                if labels:
                    assert list(meta.choices) == labels, where
                attrs = f["attributes"]
                if "CAPTURE" in attrs:
                    capture = b[f"{f['name']}_CAPTURE"]
                    assert (
                        list(capture.meta.choices)
                        == attrs["CAPTURE"]["enums"]["values"]
                    )
                if kind == "time":
                    units = b[f"{f['name']}_UNITS"]
                    assert units.value == "s" and list(units.meta.choices) == [
                        "min",
                        "s",
                        "ms",
                        "us",
                    ]
                if ftype == "pos_out":
                    assert b[f"{f['name']}_SCALE"].value == 1.0
                    assert b[f"{f['name']}_OFFSET"].value == 0.0
                    assert b[f"{f['name']}_UNITS"].value == ""
                if ftype == "table":
                    assert list(meta.elements) == [
                        c["name"] for c in f["table_columns"]
                    ]
                value = f["value_instance1"].get("value")
                if value is not None and ftype != "table":
                    got = b[f["name"]].value
                    if isinstance(meta, BooleanMeta):
                        assert got == (value == "1"), where
                    elif isinstance(meta, NumberMeta):
                        assert got == float(value), where
                    else:
                        assert got == value, where

    run(sim, tmp_path, body)


def test_a_write_by_another_client_shows_up_within_two_polls(sim, tmp_path):
    async def body(process, raw):
        pcomp = child(process, "PCOMP1")
        polls = process.get_controller(MRI).parts["zebra2"].box
        assert await raw.ask("PCOMP1.START=1234") == ["OK"]
        assert await raw.ask("CLOCK1.PERIOD.UNITS=ms") == ["OK"]
        before = polls.polls
        await until(lambda: polls.polls >= before + 2, what="two polls")
        assert pcomp.START.value == 1234
        assert child(process, "CLOCK1").PERIOD_UNITS.value == "ms"
        # a table written by the other client is re-read
        assert await raw.ask("SEQ.TABLE<\n5\n0\n0\n7\n") == ["OK"]
        before = polls.polls
        await until(lambda: polls.polls >= before + 2, what="two polls")
        table = child(process, "SEQ").TABLE.value
        assert table["REPEATS"] == (5,) and table["TIME2"] == (7,)

    run(sim, tmp_path, body)


def test_a_put_is_one_write_to_the_box(sim, tmp_path):
    async def body(process, raw):
        await process.put([f"{MRI}:PCOMP1", "START"], 42)
        assert child(process, "PCOMP1").START.value == 42
        assert await raw.ask("PCOMP1.START?") == ["OK =42"]
        await process.put([f"{MRI}:PCOMP1", "INP"], "COUNTER1.OUT")
        assert await raw.ask("PCOMP1.INP?") == ["OK =COUNTER1.OUT"]
        await process.put([f"{MRI}:COUNTER2", "OUT_SCALE"], 0.5)
        assert await raw.ask("COUNTER2.OUT.SCALE?") == ["OK =0.5"]
        await process.put([f"{MRI}:CLOCK1", "PERIOD_UNITS"], "ms")
        await process.put([f"{MRI}:CLOCK1", "PERIOD"], 100.0)
        assert await raw.ask("CLOCK1.PERIOD.RAW?") == ["OK =12500000"]
        rows = [{"REPEATS": 2, "TRIGGER": "BITA=1", "POSITION": -3, "TIME2": 9}]
        await process.put([f"{MRI}:SEQ", "TABLE"], rows)
        assert await raw.ask("SEQ.TABLE?") == [
            str(2 | 2 << 16),
            str(2**32 - 3),
            "0",
            "9",
        ]
        table = child(process, "SEQ").TABLE.value
        assert table["TRIGGER"] == ("BITA=1",) and table["POSITION"] == (-3,)
        # the mux wiring as data
        await until(
            lambda: (
                {"sink": "PCOMP1.INP", "source": "COUNTER1.OUT", "kind": "pos"}
                in process.get_controller(MRI).parts["zebra2"].wiring_rows()
            ),
            what="PCOMP1.INP in the wiring",
        )
        # a write-only field is a method
        await process.post([f"{MRI}:SRGATE1", "FORCE_SET"])

    run(sim, tmp_path, body)


@pytest.mark.parametrize(
    "block, field, value, text",
    [
        ("CALC", "SHIFT", 3, "Number out of range"),
        ("PCOMP1", "DIR", "Sideways", "Invalid enumeration value"),
        ("SEQ", "TABLE", [1, 2, 3], "Table write is not a whole number of rows"),
    ],
)
def test_a_bad_put_returns_the_boxs_error_and_changes_nothing(
    sim, tmp_path, block, field, value, text
):
    async def body(process, raw):
        attr = child(process, block)[field]
        before = attr.value
        on_box = await raw.ask(f"{block}.{field}?")
        with pytest.raises(Zebra2Error) as e:
            await process.put([f"{MRI}:{block}", field], value)
        assert text in str(e.value)
        assert f"{block}.{field}" in str(e.value)  # names block and field
        assert attr.value == before
        assert await raw.ask(f"{block}.{field}?") == on_box

    run(sim, tmp_path, body)


def test_the_example_design_drives_the_box_and_a_followed_field_faults(sim, tmp_path):
    async def body(process, raw):
        await process.put([MRI, "design"], "example")
        manager = process.get_block(MRI)
        assert manager.state.value == "Ready", manager.health.value
        assert await raw.ask("PCOMP2.WIDTH?") == ["OK =32"]
        assert await raw.ask("SEQ.TABLE?") == [
            "3",
            "0",
            "32",
            "45",
            str(1 | 2 << 16),
            "0",
            "3",
            "5",
        ]
        await process.put([MRI, "Start"], 77)
        assert await raw.ask("PCOMP1.START?") == ["OK =77"]
        await until(lambda: child(process, "PCOMP2").START.value == 77, what="follow")
        assert await raw.ask("PCOMP2.START?") == ["OK =77"]
        await process.put([f"{MRI}:COUNTER1", "OUT_CAPTURE"], "Value")
        assert await raw.ask("*CAPTURE?") == ["COUNTER1.OUT Value"]
        await process.post([MRI, "Arm"])  # the exported PCAP.ARM (*PCAP.ARM=)
        assert (await raw.ask("*PCAP.COMPLETION?")) == ["OK =Busy"]
        await process.post([f"{MRI}:PCAP", "DISARM"])
        assert manager.state.value == "Ready", manager.health.value
        # another client writes the followed field
        assert await raw.ask("PCOMP2.START=5") == ["OK"]
        await until(lambda: manager.state.value == "Fault", what="Fault")
        assert "PCOMP2.START" in manager.health.value
        # a reset writes the followed value back to the box
        await process.post([MRI, "reset"])
        assert manager.state.value == "Ready", manager.health.value
        assert await raw.ask("PCOMP2.START?") == ["OK =77"]

    run(sim, tmp_path, body)


def test_killing_the_box_gives_invalid_alarms_and_restarting_it_recovers(sim, tmp_path):
    async def body(process, raw):
        manager = process.get_block(MRI)
        pcomp = child(process, "PCOMP1")
        await raw.close()
        sim.kill()
        await until(
            lambda: pcomp.START.alarm.severity is AlarmSeverity.INVALID_ALARM,
            timeout=10,
            what="INVALID alarm",
        )
        await until(lambda: manager.health.value != "OK", what="manager health")
        assert f"{sim.host}:{sim.control_port}" in manager.health.value
        assert f"{sim.host}:{sim.control_port}" in pcomp.health.value
        with pytest.raises(Exception, match="not connected"):
            await process.put([f"{MRI}:PCOMP1", "START"], 3)
        sim.start()  # the same ports
        await until(lambda: manager.health.value == "OK", timeout=15, what="back")
        await until(lambda: pcomp.START.alarm.severity == 0, what="alarm cleared")
        await process.put([f"{MRI}:PCOMP1", "START"], 3)
        assert pcomp.START.value == 3

    run(sim, tmp_path, body)


def test_a_box_not_there_at_start_faults_the_manager_and_a_reset_makes_it(
    sim, tmp_path
):
    sim.kill()

    async def main():
        process = manager_process(sim, tmp_path)
        await process.start()
        manager = process.get_block(MRI)
        try:
            assert manager.state.value == "Fault"
            assert f"{sim.host}:{sim.control_port}: cannot connect" in (
                manager.health.value
            )
            assert process.get_controller(MRI).children == {}
            sim.start()
            await process.post([MRI, "reset"])
            assert manager.state.value == "Ready", manager.health.value
            assert len(process.get_controller(MRI).children) == 19
            assert child(process, "PCOMP1").state.value == "Ready"
        finally:
            await process.stop()

    asyncio.run(main())


def test_a_field_the_box_cannot_read_has_an_invalid_alarm(tmp_path):
    box = SimBox("tier1")  # its SYSTEM block's reads fail: "(error)"
    box.start()
    try:

        async def body(process, raw):
            manager = process.get_block(MRI)
            assert manager.state.value == "Ready", manager.health.value
            system = child(process, "SYSTEM")
            for name in ("TEMP_ZYNQ", "TEMP_PSU", "VCCINT"):
                alarm = system[name].alarm
                assert alarm.severity is AlarmSeverity.INVALID_ALARM, name
                assert f"SYSTEM.{name}: the box cannot read it" == alarm.message
            assert child(process, "PCOMP1").START.alarm.severity == 0
            assert len(process.get_controller(MRI).children) > 29

        run(box, tmp_path, body)
    finally:
        box.kill()

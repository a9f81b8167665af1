"""The control port client, the introspection and the formats, against a
scripted server that replays the recorded tier-2 replies (``replay.py``)."""

from __future__ import annotations

import asyncio

import pytest

from malcolm.io.zebra2 import (
    ControlClient,
    TableColumn,
    Zebra2Disconnected,
    Zebra2Error,
    Zebra2Timeout,
    introspect,
    pack_table,
    parse_change,
    unpack_table,
)

from .replay import TIER2, ReplayServer

pytestmark = pytest.mark.skipif(not TIER2.exists(), reason="no ../shared/zebra2")


async def _with_server(body):
    server = ReplayServer()
    port = await server.start()
    client = ControlClient("127.0.0.1", port, timeout=2)
    try:
        await client.connect()
        return await body(server, client)
    finally:
        await client.close()
        await server.close()


def test_pipelined_replies_match_their_commands_in_order():
    async def body(server, client):
        commands = ["*IDN?", "PCOMP1.START=7", "PCOMP1.START?", "*BLOCKS?", "NOPE?"]
        replies = await client.send_many(commands)
        # all five were sent before the first reply came back
        assert server.received[-5:] == commands
        assert replies[0].value.startswith("PandA SW: 4.1-dirty FPGA: 0.1.17")
        assert replies[1].value is None and replies[1].lines is None  # OK
        assert replies[2].value == "7"
        assert replies[3].lines[:2] == ("SRGATE 2", "PCOMP 2")
        assert isinstance(replies[4], Zebra2Error)
        assert replies[4].text == "No such field"
        assert str(replies[4]) == "NOPE?: No such field"

    asyncio.run(_with_server(body))


def test_err_replies_raise_the_servers_text_and_the_connection_stays():
    async def body(server, client):
        with pytest.raises(Zebra2Error, match="Invalid enumeration value") as e:
            await client.put("PCOMP1.DIR", "Sideways")
        assert e.value.command == "PCOMP1.DIR=Sideways"
        with pytest.raises(Zebra2Error, match="Number out of range"):
            await client.put("CALC.SHIFT", "3")
        assert await client.get("PCOMP1.DIR") == "Positive"  # unchanged, connected
        with pytest.raises(Zebra2Error, match="not a whole number of rows"):
            await client.put_table("SEQ.TABLE", [1, 2, 3])
        await client.put_table("SEQ.TABLE", [1, 2, 3, 4])
        assert await client.get_lines("SEQ.TABLE") == ["1", "2", "3", "4"]

    asyncio.run(_with_server(body))


def test_a_reply_that_does_not_come_times_out_and_drops_the_connection():
    async def main():
        async def silent(reader, writer):
            await reader.read()  # reads, never answers
            writer.close()

        server = await asyncio.start_server(silent, "127.0.0.1", 0)
        port = server.sockets[0].getsockname()[1]
        client = ControlClient("127.0.0.1", port, timeout=0.2)
        await client.connect()
        with pytest.raises(Zebra2Timeout, match=r"no reply to '\*IDN\?' in 0.2 s"):
            await client.send("*IDN?")
        assert not client.connected
        with pytest.raises(Zebra2Disconnected, match="no reply"):
            await client.send("*IDN?")
        await client.close()
        server.close()
        await server.wait_closed()

    asyncio.run(main())


def test_a_lost_box_fails_commands_in_flight_and_a_reconnect_works():
    async def body(server, client):
        assert await client.get("PCOMP1.START") == "0"
        server.drop_clients()
        with pytest.raises(Zebra2Disconnected):
            for _ in range(100):  # the loss is seen when the socket closes
                await client.get("PCOMP1.START")
                await asyncio.sleep(0.01)
        assert not client.connected
        await client.connect()
        assert await client.get("PCOMP1.START") == "0"

    asyncio.run(_with_server(body))


def test_nobody_listening_is_a_disconnected_error_naming_the_address():
    async def main():
        client = ControlClient("127.0.0.1", 1, timeout=1)
        with pytest.raises(Zebra2Disconnected, match="127.0.0.1:1: cannot connect"):
            await client.connect()

    asyncio.run(main())


def test_introspection_of_tier_2_gives_every_block_and_field():
    async def body(server, client):
        layout = await introspect(client)
        assert layout.idn.startswith("PandA SW")
        recorded = server.details
        assert [b.name for b in layout.blocks] == list(recorded)
        for b in layout.blocks:
            assert b.count == recorded[b.name]["count"]
            assert [f.name for f in b.fields] == [
                f["name"] for f in recorded[b.name]["fields"]
            ]
        pcomp = layout.block("PCOMP")
        assert pcomp.instances == ["PCOMP1", "PCOMP2"]
        assert layout.block("SEQ").instances == ["SEQ"]
        inp = next(f for f in pcomp.fields if f.name == "INP")
        assert inp.labels == ("CALC.OUT", "COUNTER1.OUT", "COUNTER2.OUT", "ZERO")
        out = next(f for f in layout.block("COUNTER").fields if f.name == "OUT")
        assert out.attribute_labels["CAPTURE"][-1] == "Min Max Mean"
        period = next(f for f in layout.block("CLOCK").fields if f.name == "PERIOD")
        assert period.kind == "time"
        assert period.attribute_labels["UNITS"] == ("min", "s", "ms", "us")
        table = next(f for f in layout.block("SEQ").fields if f.name == "TABLE")
        assert table.fixed["ROW_WORDS"] == "4"
        trigger = next(c for c in table.columns if c.name == "TRIGGER")
        assert (trigger.high, trigger.low, trigger.labels[2]) == (19, 16, "BITA=1")

    asyncio.run(_with_server(body))


def test_changes_lines_are_parsed():
    assert parse_change("PCOMP1.START=5").value == "5"
    change = parse_change("COUNTER1.OUT.UNITS=mm")
    assert (change.block, change.field, change.attribute) == (
        "COUNTER1",
        "OUT",
        "UNITS",
    )
    assert parse_change("SEQ.TABLE<").kind == "table"
    assert parse_change("SYSTEM.TEMP_ZYNQ (error)").kind == "error"
    assert parse_change("*METADATA.LABEL_X=1") is None
    assert parse_change("PCOMP1.START=").value == ""


def test_table_words_round_trip_through_columns():
    columns = [
        TableColumn("REPEATS", 15, 0, "uint"),
        TableColumn("TRIGGER", 19, 16, "enum", labels=("Immediate", "BITA=0")),
        TableColumn("OUTA1", 20, 20, "uint"),
        TableColumn("POSITION", 63, 32, "int"),
        TableColumn("TIME2", 127, 96, "uint"),
    ]
    table = {
        "REPEATS": [3, 65535],
        "TRIGGER": ["BITA=0", "Immediate"],
        "OUTA1": [1, 0],
        "POSITION": [-5, 2**31 - 1],
        "TIME2": [20, 2**32 - 1],
    }
    words = pack_table(columns, 4, table)
    assert words[:4] == [3 | 1 << 16 | 1 << 20, 2**32 - 5, 0, 20]
    assert unpack_table(columns, 4, words) == table

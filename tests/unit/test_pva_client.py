"""The pvAccess client's own pieces against a plain p4p server holding the
§2 structure of a block (malcolm.io.pva.convert.to_value): the mirror built
from it, monitor updates, a lost and a returning server; error texts and
argument types. The served-process tests are in tests/system/test_client*.py.
"""

from __future__ import annotations

import asyncio
import socket

import pytest
from p4p import Value
from p4p.server import Server
from p4p.server.thread import SharedPV

from malcolm.controllers.stateful import StatefulController
from malcolm.core import (
    AlarmSeverity,
    AlarmStatus,
    BadValueError,
    MapMeta,
    NotAllowedError,
    NumberArrayMeta,
    NumberMeta,
    Process,
    StringArrayMeta,
    TableMeta,
)
from malcolm.io import ConnectionState, DisconnectedError
from malcolm.io.pva.client import RemoteBlock
from malcolm.io.pva.client_channel import parse_address
from malcolm.io.pva.client_convert import RemoteError, args_value, remote_error
from malcolm.io.pva.convert import to_dict, to_value
from malcolm.parts.demo import CounterPart


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class PlainServer:
    """A bare p4p server with one SharedPV holding a block's structure."""

    def __init__(self, port: int, data: dict) -> None:
        self.port = port
        self.pv = SharedPV(initial=to_value(data))
        self.server = Server(
            providers=[{"COUNTER": self.pv}],
            conf={
                "EPICS_PVAS_INTF_ADDR_LIST": "127.0.0.1",
                "EPICS_PVAS_SERVER_PORT": str(port),
                "EPICS_PVAS_BROADCAST_PORT": str(free_port()),
            },
            useenv=False,
        )

    def post_counter(self, value: float) -> None:
        update = Value(self.pv.current().type(), {})
        update["counter.value"] = value
        update["counter.alarm.severity"] = 1
        self.pv.post(update)

    def stop(self) -> None:
        self.pv.close()
        self.server.stop()


def counter_block() -> dict:
    return StatefulController("COUNTER", [CounterPart("counter")]).block.to_dict()


async def wait_for(predicate, what: str, timeout: float = 10.0) -> None:
    loop = asyncio.get_running_loop()
    end = loop.time() + timeout
    while not predicate():
        if loop.time() > end:
            raise AssertionError(f"not seen within {timeout} s: {what}")
        await asyncio.sleep(0.02)


def test_mirror_follows_a_plain_server_and_survives_its_loss():
    port = free_port()
    data = counter_block()
    served = PlainServer(port, data)

    async def main():
        nonlocal served
        process = Process("b")
        remote = RemoteBlock("COUNTER", f"127.0.0.1:{port}", connect_timeout=5)
        process.add_controller(remote)
        await process.start()
        try:
            block = process.get_block("COUNTER")
            # the whole structure, field for field, as the server holds it
            mirrored = process.get(["COUNTER"])
            assert list(mirrored) == list(data)
            assert mirrored["counter"]["meta"] == data["counter"]["meta"]
            assert mirrored["increment"]["meta"] == data["increment"]["meta"]
            assert block.counter.value == 0.0
            # a monitor update changes one field's value and alarm
            seen = []
            process.subscribe(["COUNTER", "counter", "value"], seen.append, False)
            served.post_counter(7.0)
            await wait_for(lambda: block.counter.value == 7.0, "counter = 7")
            assert block.counter.alarm.severity is AlarmSeverity.MINOR_ALARM
            assert seen[-1] == 7.0
            # the server goes: INVALID alarms, health, methods not callable
            served.stop()
            await wait_for(
                lambda: remote._channel.state is ConnectionState.DISCONNECTED,
                "disconnected",
            )
            assert block.counter.alarm.severity is AlarmSeverity.INVALID_ALARM
            assert block.counter.alarm.status is AlarmStatus.CLIENT_STATUS
            assert block.health.value == (
                f"pva://127.0.0.1:{port}/COUNTER: connection lost"
            )
            assert not block.increment.meta.writeable
            with pytest.raises(DisconnectedError, match="COUNTER: connection lost"):
                await process.post(["COUNTER", "increment"])
            # it comes back with another value: refreshed, alarms cleared
            data["counter"]["value"] = 3.0
            served = PlainServer(port, data)
            await wait_for(lambda: block.counter.value == 3.0, "counter = 3", 20)
            assert block.counter.alarm.severity is AlarmSeverity.NO_ALARM
            assert block.health.value == "OK"
            assert block.increment.meta.writeable
        finally:
            await process.stop()
            served.stop()

    asyncio.run(main())


def test_a_server_that_is_not_there_leaves_the_block_waiting():
    port = free_port()

    async def main():
        process = Process("b")
        process.add_controller(
            RemoteBlock("NOBODY", f"127.0.0.1:{port}", connect_timeout=0.2)
        )
        await process.start()
        block = process.get_block("NOBODY")
        assert list(block) == ["health", "state"]
        assert block.state.value == "Disabled"
        assert block.state.alarm.severity is AlarmSeverity.INVALID_ALARM
        assert block.health.value == (
            f"pva://127.0.0.1:{port}/NOBODY: not connected within 0.2 s; still trying"
        )
        assert block.health.alarm.severity is AlarmSeverity.INVALID_ALARM
        with pytest.raises(DisconnectedError, match="NOBODY"):
            await process.put(["NOBODY", "health"], "x")
        await process.stop()

    asyncio.run(main())


def test_remote_errors_come_back_as_their_type():
    e = remote_error("NotAllowedError: SCAN: run() is not allowed in state Ready")
    assert type(e) is NotAllowedError
    assert str(e) == "SCAN: run() is not allowed in state Ready"
    e = remote_error("BadValueError: HELLO.greet.sleep: 'x' is not a number")
    assert isinstance(e, BadValueError) and str(e).startswith("HELLO.greet.sleep")
    e = remote_error("ZeroDivisionError: division by zero")
    assert type(e) is RemoteError and str(e) == "ZeroDivisionError: division by zero"
    e = remote_error("Disconnected", "pva://h:1/X.y")
    assert type(e) is RemoteError and str(e) == "pva://h:1/X.y: Disconnected"


def test_arguments_are_typed_by_the_method_takes():
    takes = MapMeta(
        {
            "n": NumberMeta("int32"),
            "xs": NumberArrayMeta("float32"),
            "names": StringArrayMeta(),
            "table": TableMeta({"a": NumberArrayMeta("int16")}),
        }
    )
    generator = {
        "typeid": "scanpointgenerator:generator/CompoundGenerator:1.0",
        "generators": [
            {
                "typeid": "scanpointgenerator:generator/LineGenerator:1.0",
                "axes": ["x"],
                "size": 3,
            }
        ],
        "duration": 0.1,
    }
    value = args_value(
        {
            "n": 3,
            "xs": (1.0, 2.0),
            "names": [],
            "table": [{"a": 1}, {"a": 2}],
            "generator": generator,
            "skipped": None,
        },
        takes,
    )
    assert isinstance(value, Value)
    t = value.type()
    assert (t["n"], t["xs"], t["names"]) == ("i", "af", "as")
    assert t["table"].getID() == "malcolm:core/Table:1.0"
    assert "skipped" not in value.keys()
    back = to_dict(value)
    assert back["n"] == 3 and back["names"] == [] and back["table"]["a"] == [1, 2]
    assert back["generator"]["typeid"] == generator["typeid"]
    assert back["generator"]["generators"][0]["axes"] == ["x"]


def test_addresses():
    assert parse_address("127.0.0.1:5075") == ("127.0.0.1", 5075)
    assert parse_address("localhost") == ("localhost", 5075)
    with pytest.raises(ValueError, match="port 'x' is not a number"):
        parse_address("h:x")
    with pytest.raises(ValueError, match="out of range"):
        parse_address("h:70000")


def test_the_block_list_names_the_other_blocks():
    from malcolm.core import NotWriteableError
    from malcolm.io.pva.client_blocklist import add_block_list

    async def main():
        process = Process("a")
        process.add_controller(StatefulController("COUNTER", [CounterPart("c")]))
        block_list = add_block_list(process)
        await process.start()
        assert process.get(["localhost", "blocks", "value"]) == ["COUNTER"]
        process.add_controller(StatefulController("LATER", []))
        block_list.refresh()
        assert process.get(["localhost", "blocks", "value"]) == ["COUNTER", "LATER"]
        with pytest.raises(NotWriteableError, match="localhost.blocks is read-only"):
            await process.put(["localhost", "blocks"], ["x"])
        await process.stop()

    asyncio.run(main())


def test_a_served_block_that_changes_shape_goes_and_comes_back():
    """Against malcolm's own server in this process: a field added at run
    time appears in the mirror; a block removed shows as lost; made again,
    it is back."""
    from malcolm.core import Attribute
    from malcolm.io.pva.server import start_pva_server

    async def main():
        port = free_port()
        a = Process("a")
        a.add_controller(StatefulController("C", [CounterPart("counter")]))
        await a.start()
        server = await start_pva_server(a, port)
        b = Process("b")
        b.add_controller(RemoteBlock("C", f"127.0.0.1:{port}"))
        await b.start()
        try:
            mirror = b.get_block("C")
            assert "extra" not in mirror
            a.get_block("C").add(Attribute("extra", NumberMeta("int32"), 5))
            await wait_for(lambda: "extra" in mirror, "extra")
            assert mirror.extra.value == 5
            a.get_block("C").counter.set_value(9.0)
            await wait_for(lambda: mirror.counter.value == 9.0, "counter 9")
            await a.get_controller("C").stop()
            a.remove_controller("C")
            await wait_for(lambda: mirror.health.value != "OK", "C gone")
            assert mirror.counter.alarm.severity is AlarmSeverity.INVALID_ALARM
            a.add_controller(StatefulController("C", [CounterPart("counter")]))
            await a.get_controller("C").start()
            await wait_for(lambda: mirror.health.value == "OK", "C back")
            assert "extra" not in mirror and mirror.counter.value == 0.0
        finally:
            await b.stop()
            await server.close()
            await a.stop()

    asyncio.run(main())

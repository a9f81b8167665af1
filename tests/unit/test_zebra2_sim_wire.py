"""The simulated PandA answers every recorded introspection command as the
recorded server did (the ``raw`` map of introspection-tier{1,2}.json), and
the wire rules of /work/shared/zebra2/README.md hold: line limit, pipelining,
split lines, a dropped connection never kills the server.

The helpers here (`Wire`, `running`) are used by the other
test_zebra2_sim_* modules.
"""

from __future__ import annotations

import asyncio
import functools
import json
from contextlib import asynccontextmanager
from importlib import resources

import pytest

from malcolm.sim.zebra2 import ManualClock, serve_zebra2


def aio(fn):
    """Run an ``async def`` test on a fresh event loop."""

    @functools.wraps(fn)
    def run(*args, **kwargs):
        return asyncio.run(fn(*args, **kwargs))

    return run


class Wire:
    """A raw control-port connection: send lines, read whole replies."""

    def __init__(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter):
        self.reader = reader
        self.writer = writer

    @classmethod
    async def open(cls, port: int, host: str = "127.0.0.1") -> Wire:
        reader, writer = await asyncio.open_connection(host, port)
        return cls(reader, writer)

    def send(self, *lines: str) -> None:
        data = "".join(line + "\n" for line in lines)
        self.writer.write(data.encode("utf-8", "surrogateescape"))

    async def line(self, timeout: float = 5.0) -> str:
        raw = await asyncio.wait_for(self.reader.readline(), timeout)
        if not raw:
            raise EOFError("connection closed")
        return raw[:-1].decode("utf-8", "surrogateescape")

    async def reply(self, timeout: float = 5.0) -> list[str]:
        """One reply: a single line, or ``!`` lines up to ``.``."""
        first = await self.line(timeout)
        lines = [first]
        if first.startswith("!") or first == ".":
            while lines[-1] != ".":
                lines.append(await self.line(timeout))
        return lines

    async def ask(self, *lines: str) -> list[str]:
        self.send(*lines)
        return await self.reply()

    async def close(self) -> None:
        self.writer.close()
        try:
            await self.writer.wait_closed()
        except ConnectionError:
            pass


@asynccontextmanager
async def running(layout: str = "tier2", **kwargs):
    """A simulator on free loopback ports, closed afterwards."""
    server = await serve_zebra2("127.0.0.1", 0, 0, layout, **kwargs)
    try:
        yield server
    finally:
        await server.close()


def recorded(layout: str) -> dict:
    text = (
        resources.files("malcolm.sim.zebra2")
        .joinpath("data", f"introspection-{layout}.json")
        .read_text()
    )
    return json.loads(text)


@pytest.mark.parametrize("layout", ["tier1", "tier2"])
@aio
async def test_every_recorded_introspection_reply(layout: str) -> None:
    data = recorded(layout)
    async with running(layout, clock=ManualClock()) as server:
        # each *CHANGES query was the first call on its own new connection
        for command, expected in data["changes_initial"].items():
            wire = await Wire.open(server.control_port)
            assert await wire.ask(command) == expected, command
            await wire.close()
        wire = await Wire.open(server.control_port)
        mismatches, compared = [], 0
        for command, expected in data["raw"].items():
            command = command.split("  #")[0]
            if command.startswith("*CHANGES") or command == "*WHO?":
                continue
            got = await wire.ask(command)
            compared += 1
            if got != expected:
                mismatches.append((command, expected, got))
        await wire.close()
    assert compared > 1000
    assert mismatches == [], f"{len(mismatches)} replies differ: {mismatches[:5]}"


@aio
async def test_who_lists_connections_with_trailing_space() -> None:
    async with running() as server:
        a = await Wire.open(server.control_port)
        b = await Wire.open(server.control_port)
        reply = await a.ask("*WHO?")
        assert len(reply) == 3 and reply[-1] == "."
        for item in reply[:-1]:
            assert item.startswith("!20") and item.endswith(" ")
            assert " config 127.0.0.1:" in item
        await a.close()
        await b.close()


@aio
async def test_line_limit_closes_connection_and_server_lives_on() -> None:
    async with running() as server:
        wire = await Wire.open(server.control_port)
        wire.send("*ECHO " + "y" * 1015 + "?")  # 1023 bytes with the newline
        assert await wire.reply() == ["ERR Result too long"]
        wire.send("*ECHO " + "y" * 1016 + "?")  # 1024 bytes
        assert await wire.reader.read() == b""  # closed without a reply
        await wire.close()
        again = await Wire.open(server.control_port)
        assert await again.ask("*ECHO hi?") == ["OK =hi"]
        await again.close()


@aio
async def test_pipelined_and_split_commands() -> None:
    async with running() as server:
        wire = await Wire.open(server.control_port)
        wire.send("PCOMP1.START=3", "PCOMP1.START?", "FOO?", "*ENUMS.PCOMP1.DIR?")
        assert await wire.reply() == ["OK"]
        assert await wire.reply() == ["OK =3"]
        assert await wire.reply() == ["ERR No such block"]
        assert await wire.reply() == ["!Positive", "!Negative", "!Either", "."]
        wire.writer.write(b"PCOMP1.ST")
        await wire.writer.drain()
        await asyncio.sleep(0.05)
        wire.writer.write(b"ART?\n")
        assert await wire.reply() == ["OK =3"]
        await wire.close()


@aio
async def test_connection_dropped_mid_table_write() -> None:
    async with running() as server:
        wire = await Wire.open(server.control_port)
        wire.send("SEQ.TABLE<", "1 2 3 4")
        await wire.close()
        other = await Wire.open(server.control_port)
        assert await other.ask("SEQ.TABLE.LENGTH?") == ["OK =0"]
        await other.close()

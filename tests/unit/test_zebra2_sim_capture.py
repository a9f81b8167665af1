"""The data port against capture-tier1.txt and capture-tier2.txt.

Each recorded run is replayed: the same data clients with the same option
lines, the control commands at their recorded times (on a `ManualClock`).
Tier 1's dumb simulator fills every word with ``(sample << 8) | word``, so
every client's bytes are compared with the recorded bytes (rebuilt from the
text lines and hex dumps), ignoring only arm_time/start_time and where FRAMED
data is cut into frames.  Tier 2's values come from its clock and counters:
the headers are compared exactly and the samples by what they must be
(a 10 Hz clock, counters stepping 1 and 5, scaling, Mean = Min = Max, the
RAW Mean a sum over GATE_DURATION), the same in every format.
"""

from __future__ import annotations

import asyncio
import re
import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

from malcolm.sim.zebra2 import ManualClock

from .test_zebra2_sim_transcripts import unescape
from .test_zebra2_sim_wire import Wire, aio, running

RECORDINGS = Path(__file__).with_name("zebra2_recordings")  # from /work/shared/zebra2
_TIMES = re.compile(rb'(arm_time|start_time)(: |=")[0-9T:.\-]+Z')
_HEX = re.compile(r"^    [0-9a-f]{4}  ((?:[0-9a-f]{2} )+)")


@dataclass
class Recorded:
    """One recorded data client: its options and every byte it received."""

    options: str
    late: bool
    data: bytearray = field(default_factory=bytearray)


@dataclass
class Control:
    time: float
    command: str | None  # None: the late data client connects
    replies: list[str] = field(default_factory=list)


def parse_capture(path: Path) -> tuple[list[Control], list[Recorded]]:
    controls: list[Control] = []
    clients: list[Recorded] = []
    section = "control"
    for text in path.read_text().splitlines():
        if m := re.match(
            r"DATA PORT \(8889\) client \d+: sent options line '(.*)'", text
        ):
            options = m.group(1)
            assert options.endswith("\\n")
            clients.append(Recorded(options[:-2], "connected late" in text))
            section = "data"
            continue
        if section == "control":
            if m := re.match(r"^\[\s*([\d.]+)\] < (.*)$", text):
                controls.append(Control(float(m.group(1)), m.group(2)))
            elif m := re.match(r"^\[\s*([\d.]+)\] ## data client \d+ connects", text):
                controls.append(Control(float(m.group(1)), None))
            elif m := re.match(r"^\s+> (.*)$", text):
                controls[-1].replies.append(m.group(1))
        elif text == "|":
            clients[-1].data += b"\n"
        elif text.startswith("| "):
            clients[-1].data += unescape(text[2:]) + b"\n"
        elif m := _HEX.match(text):
            clients[-1].data += bytes.fromhex(m.group(1))
    return controls, clients


def normalise(data: bytes, framed: bool) -> bytes:
    """Times blanked, FRAMED frames' 8-byte prefixes dropped."""
    data = _TIMES.sub(rb"\1\2T", bytes(data))
    if not framed:
        return data
    out, pos = bytearray(), 0
    while True:
        at = data.find(b"BIN ", pos)
        if at < 0:
            return bytes(out + data[pos:])
        (length,) = struct.unpack_from("<I", data, at + 4)
        out += data[pos:at] + data[at + 8 : at + length]
        pos = at + length


class DataWire:
    """A data-port client that records everything it receives."""

    def __init__(self, options: str) -> None:
        self.options = options
        self.data = bytearray()
        self.eof = False

    async def connect(self, port: int) -> None:
        self.reader, self.writer = await asyncio.open_connection("127.0.0.1", port)
        self.writer.write(self.options.encode() + b"\n")
        self.task = asyncio.ensure_future(self._read())

    async def _read(self) -> None:
        while chunk := await self.reader.read(65536):
            self.data += chunk
        self.eof = True

    async def close(self) -> None:
        self.task.cancel()
        self.writer.close()


async def run_capture(layout: str) -> tuple[list[Control], list[Recorded], dict]:
    controls, recorded = parse_capture(RECORDINGS / f"capture-{layout}.txt")
    clock = ManualClock()
    got_replies: list[list[str]] = []
    async with running(layout, clock=clock, disarm_completion="Ok") as server:
        wires = [DataWire(r.options) for r in recorded]
        for wire, rec in zip(wires, recorded):
            if not rec.late:
                await wire.connect(server.data_port)
        await asyncio.sleep(0.2)  # every option line read
        control = await Wire.open(server.control_port)
        late = iter(w for w, r in zip(wires, recorded) if r.late)
        for step in controls:
            clock.advance(step.time - clock.now())
            if step.command is None:
                await next(late).connect(server.data_port)
                await asyncio.sleep(0.1)
                continue
            got_replies.append(await control.ask(step.command))
            await asyncio.sleep(0.02)  # data written, one-shot clients gone
        await asyncio.sleep(0.3)
        for wire in wires:
            await wire.close()
        await control.close()
    return controls, recorded, {"replies": got_replies, "wires": wires}


@aio
async def test_tier1_every_client_byte_for_byte() -> None:
    controls, recorded, got = await run_capture("tier1")
    assert len(recorded) == 14
    for step, reply in zip([c for c in controls if c.command], got["replies"]):
        assert reply == step.replies, step.command
    for rec, wire in zip(recorded, got["wires"]):
        framed = "FRAMED" in rec.options.split() and "ASCII" not in rec.options
        assert normalise(wire.data, framed) == normalise(rec.data, framed), rec.options
        # one-shot, BARE and refused clients are closed by the server
        closes = any(o in rec.options for o in ("ONE_SHOT", "BARE", "NOSUCH"))
        assert wire.eof == closes, rec.options


def ascii_samples(data: bytes) -> list[list[list[float]]]:
    """Each experiment's ASCII sample rows."""
    experiments, rows, in_fields = [], None, False
    for line in data.decode().splitlines():
        if line == "fields:":
            in_fields = True
        elif in_fields and line == "":
            in_fields, rows = False, []
        elif line.startswith("END "):
            experiments.append(rows)
            rows = None
        elif rows is not None:
            rows.append([float(x) for x in line.split()])
    return experiments


def framed_samples(data: bytes, dtype: np.dtype) -> list[np.ndarray]:
    """Each experiment's samples from FRAMED data."""
    experiments, payload, pos = [], bytearray(), data.find(b"</header>\n\n")
    while True:
        bin_at, end_at = data.find(b"BIN ", pos), data.find(b"END ", pos)
        if bin_at >= 0 and (end_at < 0 or bin_at < end_at):
            (length,) = struct.unpack_from("<I", data, bin_at + 4)
            payload += data[bin_at + 8 : bin_at + length]
            pos = bin_at + length
        elif end_at >= 0:
            experiments.append(np.frombuffer(bytes(payload), dtype=dtype))
            payload = bytearray()
            pos = data.find(b"\n", end_at)
        else:
            return experiments


SCALED = np.dtype([("bits", "<u4")] + [(f"f{i}", "<f8") for i in range(6)])
RAW = np.dtype(
    [("bits", "<u4"), ("gate", "<i4"), ("c1", "<i4"), ("min", "<i4"), ("max", "<i4")]
    + [("ts", "<i8"), ("mean", "<i8")]
)


@aio
async def test_tier2_headers_exact_and_samples_consistent() -> None:
    controls, recorded, got = await run_capture("tier2")
    commands = [c for c in controls if c.command]
    for step, reply in zip(commands, got["replies"]):
        if step.command in (
            "*PCAP.STATUS?",
            "*PCAP.CAPTURED?",
        ) or step.command.endswith(("OUT?", "SCALED?")):
            continue  # these depend on how fast the recorded simulation ran
        assert reply == step.replies, step.command
    ascii_wire, scaled_wire, raw_wire = got["wires"]
    for rec, wire in zip(recorded, got["wires"]):
        # the header text of both experiments is the recorded one
        ours = normalise(wire.data, False)
        theirs = normalise(rec.data, False)
        pattern = re.compile(rb"(?:<header>\n|arm_time: ).*?\n\n", re.DOTALL)
        headers = pattern.findall(theirs)
        assert len(headers) == 2 and pattern.findall(ours) == headers
    # experiment 1 is ended by PCAP.ENABLE (Ok), 2 by *PCAP.DISARM= (Ok here)
    status = [
        r for c, r in zip(commands, got["replies"]) if c.command == "*PCAP.CAPTURED?"
    ]
    n1, n2 = (int(r[0].split("=")[1]) for r in status)
    assert n1 == 7  # rising edges of the 10 Hz clock while PCAP.ENABLE was high
    assert n2 >= 5
    text = ascii_wire.data.decode()
    assert f"END {n1} Ok" in text and f"END {n2} Ok" in text
    rows1, rows2 = ascii_samples(ascii_wire.data)
    assert (len(rows1), len(rows2)) == (n1, n2)
    for rows in (rows1, rows2):
        a = np.array(rows)
        assert (a[:, 0] == 33).all()  # PCAP.ACTIVE (bit 0) and CLOCK1.OUT (bit 5)
        assert np.allclose(a[1:, 1], 0.1)  # GATE_DURATION: one clock period
        assert (np.diff(a[:, 2]) == 1).all()  # COUNTER1 steps 1
        assert np.allclose(np.diff(a[:, 3]), 2.5)  # COUNTER2 steps 5, scale 0.5
        assert (a[:, 3] == a[:, 4]).all() and (a[:, 3] == a[:, 6]).all()
        assert np.allclose(np.diff(a[:, 5]), 0.1)  # TS_TRIG
        assert np.allclose(a[0, 1], a[0, 5])  # first gate = time since start
    scaled = framed_samples(bytes(scaled_wire.data), SCALED)
    raw = framed_samples(bytes(raw_wire.data), RAW)
    for rows, s, r in zip((rows1, rows2), scaled, raw):
        a = np.array(rows)
        assert np.allclose(a, np.array(s.tolist()), rtol=1e-9)
        assert (r["c1"] == a[:, 2]).all()
        assert np.allclose(r["min"] * 0.5 + 10, a[:, 3])
        assert np.allclose(r["ts"] * 8e-9, a[:, 5])
        assert (r["mean"] == r["min"].astype(np.int64) * r["gate"]).all()
        assert np.allclose(r["mean"] / r["gate"] * 0.5 + 10, a[:, 6])


@pytest.mark.parametrize("options", ["NOSUCH", "ASCII FOO", "ASCII\r"])
@aio
async def test_invalid_option_line_is_refused(options: str) -> None:
    async with running() as server:
        wire = DataWire(options)
        await wire.connect(server.data_port)
        await asyncio.wait_for(wire.task, 5)
        assert bytes(wire.data) == b"ERR Invalid data capture option\n"
        control = await Wire.open(server.control_port)
        assert await control.ask("*PCAP.STATUS?") == ["OK =Idle 0 0"]
        await control.close()

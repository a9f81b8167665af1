"""The `pandablocks` library's own client works against the simulator: it
introspects every block and field of both layouts, reads the changes, and
captures streams (scaled and raw) whose samples it parses and counts.

`pandablocks.asyncio.AsyncioClient` always uses ports 8888/8889, so the
simulator is bound to its own loopback address (each ``isolated`` run has a
private network namespace).
"""

from __future__ import annotations

import asyncio

import numpy as np
import pytest
from pandablocks.asyncio import AsyncioClient
from pandablocks.commands import (
    Arm,
    CommandError,
    Disarm,
    Get,
    GetBlockInfo,
    GetChanges,
    GetFieldInfo,
    GetPcapBitsLabels,
    Put,
)
from pandablocks.responses import EndData, EndReason, FrameData, StartData

from malcolm.sim.zebra2 import load_layout, serve_zebra2

from .test_zebra2_sim_wire import aio

HOST = "127.0.0.11"


@pytest.mark.parametrize("layout", ["tier1", "tier2"])
@aio
async def test_pandablocks_introspects_every_block_and_field(layout: str) -> None:
    expected = load_layout(layout)
    server = await serve_zebra2(HOST, 8888, 8889, layout)
    try:
        async with AsyncioClient(HOST) as client:
            if layout == "tier1":
                # the recorded tier-1 box has a block with no description,
                # which the library's GetBlockInfo() does not accept either
                with pytest.raises(CommandError, match="No description set"):
                    await client.send(GetBlockInfo())
            blocks = await client.send(GetBlockInfo(skip_description=True))
            assert {n: b.number for n, b in blocks.items()} == {
                b.name: b.count for b in expected.blocks.values()
            }
            for name, block in expected.blocks.items():
                try:
                    fields = await client.send(GetFieldInfo(name))
                except CommandError as e:
                    # tier 1's extension-server blocks: as recorded, some
                    # field has no description or cannot be read
                    assert layout == "tier1" and name in ("DUMMY", "INTERVAL", "SYSTEM")
                    assert "No description set" in str(e) or "Extension" in str(e)
                    fields = await client.send(GetFieldInfo(name, False))
                assert list(fields) == sorted(
                    block.fields, key=lambda f: block.fields[f].index
                )
                for fname, info in fields.items():
                    fdef = block.fields[fname]
                    assert (info.type, info.subtype) == (fdef.type, fdef.subtype)
                    if info.description is not None:
                        assert info.description == fdef.desc
            changes = await client.send(GetChanges())
            assert changes.values["PCAP.ENABLE"] == "ZERO"
            labels = await client.send(GetPcapBitsLabels())
            assert len(labels) == 4 and all(len(v) == 32 for v in labels.values())
            with pytest.raises(CommandError, match="Invalid enumeration value"):
                await client.send(Put("PCOMP1.DIR", "Sideways"))
    finally:
        await server.close()


async def _capture(client: AsyncioClient, scaled: bool, stop) -> list:
    got = []
    async for data in client.data(scaled=scaled, frame_timeout=10):
        got.append(data)
        if isinstance(data, StartData):
            await stop()
        if isinstance(data, EndData):
            break
    return got


def _frames(got: list) -> np.ndarray:
    return np.concatenate([d.data for d in got if isinstance(d, FrameData)])


@aio
async def test_pandablocks_captures_a_fast_stream() -> None:
    server = await serve_zebra2(HOST, 8888, 8889, "tier2")
    try:
        async with AsyncioClient(HOST) as client:
            for field, value in [
                ("CLOCK1.PERIOD.UNITS", "us"),
                ("CLOCK1.PERIOD", "10"),  # 100 kHz
                ("CLOCK1.ENABLE", "ONE"),
                ("COUNTER1.ENABLE", "ONE"),
                ("COUNTER1.TRIG", "CLOCK1.OUT"),
                ("COUNTER1.STEP", "3"),
                ("PCAP.TRIG", "CLOCK1.OUT"),
                ("PCAP.GATE", "ONE"),
                ("COUNTER1.OUT.CAPTURE", "Value"),
                ("COUNTER1.OUT.SCALE", "0.5"),
                ("PCAP.TS_TRIG.CAPTURE", "Value"),
                ("PCAP.BITS0.CAPTURE", "Value"),
            ]:
                await client.send(Put(field, value))

            async def enable_for_a_while() -> None:
                await client.send(Put("PCAP.ENABLE", "ONE"))
                await asyncio.sleep(0.3)
                await client.send(Put("PCAP.ENABLE", "ZERO"))

            # scaled: ended by PCAP.ENABLE going low, every sample delivered
            reader = asyncio.ensure_future(_capture(client, True, _noop))
            await asyncio.sleep(0.2)
            await client.send(Arm())
            await enable_for_a_while()
            got = await asyncio.wait_for(reader, 20)
            end = got[-1]
            assert isinstance(end, EndData) and end.reason == EndReason.OK
            frames = _frames(got)
            assert len(frames) == end.samples > 10000
            counter = frames["COUNTER1.OUT.Value"]
            assert np.allclose(np.diff(counter), 1.5)  # STEP 3, SCALE 0.5
            assert np.allclose(np.diff(frames["PCAP.TS_TRIG.Value"]), 1e-5)
            captured = await client.send(Get("*PCAP.CAPTURED"))
            assert int(captured) == end.samples

            # raw: ended by *PCAP.DISARM=, which hardware reports as Disarmed
            reader = asyncio.ensure_future(_capture(client, False, _noop))
            await asyncio.sleep(0.2)
            await client.send(Arm())
            await client.send(Put("PCAP.ENABLE", "ONE"))
            await asyncio.sleep(0.2)
            await client.send(Disarm())
            got = await asyncio.wait_for(reader, 20)
            end = got[-1]
            assert isinstance(end, EndData) and end.reason == EndReason.DISARMED
            frames = _frames(got)
            assert len(frames) == end.samples > 1000
            assert (np.diff(frames["COUNTER1.OUT.Value"]) == 3).all()
            assert (np.diff(frames["PCAP.TS_TRIG.Value"]) == 1250).all()
            start = next(d for d in got if isinstance(d, StartData))
            assert [f.name for f in start.fields] == [
                "PCAP.BITS0",
                "COUNTER1.OUT",
                "PCAP.TS_TRIG",
            ]
            await client.send(Put("PCAP.ENABLE", "ZERO"))
    finally:
        await server.close()


async def _noop() -> None:
    return None


@aio
async def test_the_simulator_benchmark_prints_its_table(capsys) -> None:
    from benchmarks import zebra2_sim

    rows = await zebra2_sim.main(0.2, [0.5])
    out = capsys.readouterr().out.splitlines()
    assert out[0].split()[:2] == ["case", "measured"]
    assert len(rows) == 5 and rows[-1].case.startswith("largest rate")
    for row in rows[:4]:  # every sample made was delivered
        made, delivered = row.note.split(", END ")
        assert made == "made " + delivered.split()[0] and row.note.endswith(" Ok")

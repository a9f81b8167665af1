"""A PCAP scan of N frames as a PandA does it: a CLOCK drives a COUNTER,
PCOMP pulses as the count passes START, START+STEP, ... (PULSES of them),
PCAP triggers on PCOMP.OUT while PCOMP.ACTIVE enables and gates it, and the
capture ends by itself with ``END N Ok`` when ACTIVE falls."""

from __future__ import annotations

import asyncio

import numpy as np

from malcolm.sim.zebra2 import ManualClock

from .test_zebra2_sim_capture import DataWire, ascii_samples
from .test_zebra2_sim_wire import Wire, aio, running

SETUP = [
    "CLOCK1.PERIOD.UNITS=ms",
    "CLOCK1.PERIOD=1",
    "CLOCK1.ENABLE=ONE",
    "COUNTER1.ENABLE=ONE",
    "COUNTER1.TRIG=CLOCK1.OUT",
    "COUNTER1.STEP=1",
    "PCOMP1.INP=COUNTER1.OUT",
    "PCOMP1.START=10",
    "PCOMP1.STEP=5",
    "PCOMP1.WIDTH=2",
    "PCOMP1.PULSES=7",
    "PCAP.TRIG=PCOMP1.OUT",
    "PCAP.GATE=PCOMP1.ACTIVE",
    "PCAP.ENABLE=PCOMP1.ACTIVE",
    "COUNTER1.OUT.CAPTURE=Value",
    "PCAP.TS_TRIG.CAPTURE=Value",
    "PCAP.BITS0.CAPTURE=Value",
]


async def scan(wire: Wire, clock: ManualClock, relative: bool) -> None:
    for line in SETUP + [f"PCOMP1.RELATIVE={'Relative' if relative else 'Absolute'}"]:
        assert await wire.ask(line) == ["OK"], line
    assert await wire.ask("*PCAP.ARM=") == ["OK"]
    assert await wire.ask("PCAP.ACTIVE?") == ["OK =1"]
    assert await wire.ask("*PCAP.STATUS?") == ["OK =Busy 1 1"]
    assert await wire.ask("PCOMP1.ENABLE=ONE") == ["OK"]
    assert await wire.ask("PCOMP1.ACTIVE?") == ["OK =1"]
    clock.advance(0.0205)  # mid-scan
    assert await wire.ask("*PCAP.COMPLETION?") == ["OK =Busy"]
    clock.advance(0.1)
    assert await wire.ask("*PCAP.COMPLETION?") == ["OK =Ok"]
    assert await wire.ask("*PCAP.CAPTURED?") == ["OK =7"]
    assert await wire.ask("PCOMP1.ACTIVE?") == ["OK =0"]
    assert await wire.ask("PCOMP1.PRODUCED?") == ["OK =7"]
    assert await wire.ask("PCAP.ACTIVE?") == ["OK =0"]


@aio
async def test_pcomp_drives_an_n_frame_capture() -> None:
    clock = ManualClock()
    async with running("tier2", clock=clock) as server:
        data = DataWire("ASCII")
        await data.connect(server.data_port)
        await asyncio.sleep(0.1)
        wire = await Wire.open(server.control_port)
        await scan(wire, clock, relative=False)
        await asyncio.sleep(0.1)
        text = data.data.decode()
        assert text.rstrip().endswith("END 7 Ok")
        (rows,) = ascii_samples(data.data)
        a = np.array(rows)
        assert a[:, 1].tolist() == [10, 15, 20, 25, 30, 35, 40]  # COUNTER1.OUT
        assert np.allclose(np.diff(a[:, 2]), 0.005)  # TS_TRIG: 5 counts of 1 ms
        # BITS0: PCAP.ACTIVE (bit 0), CLOCK1.OUT (5), PCOMP1.ACTIVE and .OUT
        bits = await wire.ask("PCAP.BITS0.BITS?")
        offsets = [bits.index(f"!{n}") for n in ("PCOMP1.ACTIVE", "PCOMP1.OUT")]
        expected = 1 | 1 << 5 | sum(1 << o for o in offsets)
        assert (a[:, 0] == expected).all()
        changes = await wire.ask("*CHANGES.BITS?")
        assert "!PCOMP1.OUT=0" in changes and "!PCOMP1.ACTIVE=0" in changes
        # a second scan on the same connections, positions relative to enable
        assert await wire.ask("PCOMP1.ENABLE=ZERO") == ["OK"]
        await scan(wire, clock, relative=True)
        await asyncio.sleep(0.1)
        rows2 = ascii_samples(data.data)[1]
        steps = np.diff(np.array(rows2)[:, 1])
        assert len(rows2) == 7 and (steps == 5).all()
        await wire.close()
        await data.close()


@aio
async def test_pcomp_with_no_counter_makes_no_pulses() -> None:
    clock = ManualClock()
    async with running("tier2", clock=clock) as server:
        wire = await Wire.open(server.control_port)
        for line in ["PCOMP1.PULSES=3", "PCOMP1.STEP=1", "PCOMP1.ENABLE=ONE"]:
            assert await wire.ask(line) == ["OK"]
        clock.advance(1)
        assert await wire.ask("PCOMP1.PRODUCED?") == ["OK =0"]
        assert await wire.ask("PCOMP1.ACTIVE?") == ["OK =1"]
        assert await wire.ask("PCOMP1.STATE?") == ["OK =WAIT_RISING"]
        await wire.close()


@aio
async def test_trig_edges_of_counter_and_pcap() -> None:
    """COUNTER.TRIG_EDGE=Either counts both edges of a 1 ms clock (high for
    0.25 ms); PCAP.TRIG_EDGE=Falling samples on the falls."""
    clock = ManualClock()
    async with running("tier2", clock=clock) as server:
        data = DataWire("ASCII")
        await data.connect(server.data_port)
        await asyncio.sleep(0.1)
        wire = await Wire.open(server.control_port)
        for line in [
            "CLOCK1.PERIOD.UNITS=ms",
            "CLOCK1.PERIOD=1",
            "CLOCK1.WIDTH.UNITS=ms",
            "CLOCK1.WIDTH=0.25",
            "COUNTER1.TRIG_EDGE=Either",
            "COUNTER1.STEP=1",
            "COUNTER1.TRIG=CLOCK1.OUT",
            "COUNTER1.ENABLE=ONE",
            "CLOCK1.ENABLE=ONE",
            "PCAP.TRIG=CLOCK1.OUT",
            "PCAP.TRIG_EDGE=Falling",
            "PCAP.GATE=ONE",
            "COUNTER1.OUT.CAPTURE=Value",
            "PCAP.TS_TRIG.CAPTURE=Value",
            "*PCAP.ARM=",
            "PCAP.ENABLE=ONE",
        ]:
            assert await wire.ask(line) == ["OK"], line
        clock.advance(0.0101)
        # 10 rises (1..10 ms; the one at the enabling write's own tick is not
        # counted) and 10 falls (0.25..9.25 ms)
        assert await wire.ask("COUNTER1.OUT?") == ["OK =20"]
        assert await wire.ask("PCAP.ENABLE=ZERO") == ["OK"]
        await asyncio.sleep(0.1)
        (rows,) = ascii_samples(data.data)
        a = np.array(rows)
        assert len(a) == 10  # falls at 0.25, 1.25, ... 9.25 ms
        assert np.allclose(a[:, 1], 0.00025 + 0.001 * np.arange(10))
        assert (a[:, 0] == 1 + 2 * np.arange(10)).all()  # after each fall
        await wire.close()
        await data.close()


@aio
async def test_pcomp_enabled_before_its_clock_starts_waits_for_it() -> None:
    """The counter holds still until its clock starts (ACTIVE high, no
    pulses), then the pulses come from the counter's START, as on a box whose
    motion starts after position compare is armed."""
    clock = ManualClock()
    async with running("tier2", clock=clock) as server:
        wire = await Wire.open(server.control_port)
        for line in [
            "CLOCK1.PERIOD.UNITS=ms",
            "CLOCK1.PERIOD=1",
            "COUNTER1.TRIG=CLOCK1.OUT",
            "COUNTER1.STEP=1",
            "COUNTER1.START=10",
            "PCOMP1.INP=COUNTER1.OUT",
            "PCOMP1.START=12",
            "PCOMP1.STEP=2",
            "PCOMP1.WIDTH=1",
            "PCOMP1.PULSES=3",
            "COUNTER1.ENABLE=ONE",
            "PCOMP1.ENABLE=ONE",
        ]:
            assert await wire.ask(line) == ["OK"], line
        clock.advance(0.01)
        assert await wire.ask("PCOMP1.ACTIVE?") == ["OK =1"]
        assert await wire.ask("PCOMP1.PRODUCED?") == ["OK =0"]
        assert await wire.ask("COUNTER1.OUT?") == ["OK =10"]
        assert await wire.ask("CLOCK1.ENABLE=ONE") == ["OK"]
        clock.advance(0.1)
        assert await wire.ask("PCOMP1.PRODUCED?") == ["OK =3"]
        assert await wire.ask("PCOMP1.ACTIVE?") == ["OK =0"]
        await wire.close()

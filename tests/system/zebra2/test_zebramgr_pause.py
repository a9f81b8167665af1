"""Pause, seek back and resume, and abort, of the ZebraManager on the
simulated box: the box is disarmed, set up from the point sought and armed
again; the re-done points' rows come again later in the file with their
uniqueids, every point has a row, and abort leaves the file closed and the
box disarmed."""

from __future__ import annotations

import asyncio

import numpy as np

from malcolm.core import AbortedError
from malcolm.scan import gda

from .conftest import RawClient
from .zebramgr import MRI, read_elsewhere, wait_for, zebra_process

N = 300
M = 200
PERIOD = 0.01


def test_pause_seek_back_and_resume_redo_the_points_from_there(sim, tmp_path):
    async def main():
        process = zebra_process(sim)
        await process.start()
        try:
            block = process.get_block(MRI)
            generator = gda.compound(gda.line("x", N), duration=PERIOD)
            params = {"generator": generator, "axesToMove": ["x"]}
            await process.post([MRI, "configure"], {**params, "fileDir": str(tmp_path)})
            run = asyncio.ensure_future(process.post([MRI, "run"]))
            await wait_for(block, "completedSteps", lambda v: v >= 60)
            await process.post([MRI, "pause"], {"lastGoodStep": 40})
            paused = (block.state.value, block.completedSteps.value)
            # paused: the file is closed, the box is armed again and waits
            between = read_elsewhere(tmp_path / "zebra.h5")
            await asyncio.sleep(0.2)  # nothing comes while paused
            after_wait = read_elsewhere(tmp_path / "zebra.h5")
            await process.post([MRI, "resume"])
            await asyncio.wait_for(run, 30)
            return paused, between, after_wait, block.state.value
        finally:
            await process.stop()

    paused, between, after_wait, state = asyncio.run(main())
    assert paused == ("Paused", 40)
    assert state == "Finished"
    assert between["uniqueid"] == after_wait["uniqueid"]
    first = between["uniqueid"]
    assert len(first) >= 60 and first == list(range(1, len(first) + 1))
    data = read_elsewhere(tmp_path / "zebra.h5")
    uids = data["uniqueid"]
    # the first run's rows, then the points from 40 (uniqueid 41) again
    assert uids == first + list(range(41, N + 1))
    assert sorted(set(uids)) == list(range(1, N + 1))
    assert data["COUNTER1.OUT.Value"] == [u - 1.0 for u in uids]
    # the last row of each uniqueid is of the resumed run: its timestamps go up
    ts = np.array(data["PCAP.TS_TRIG.Value"][len(first) :])
    assert (np.diff(ts) > 0).all()


def test_seek_while_armed_and_paused_twice(sim, tmp_path):
    """A seek before the run (Armed) and two pauses in a row: each re-arms
    the box at the point sought, the file has each point's row last."""

    async def main():
        process = zebra_process(sim)
        await process.start()
        try:
            block = process.get_block(MRI)
            generator = gda.compound(gda.line("x", M), duration=0.005)
            await process.post(
                [MRI, "configure"], {"generator": generator, "fileDir": str(tmp_path)}
            )
            await process.put([MRI, "completedSteps"], 10)  # seek while Armed
            armed = (block.state.value, block.completedSteps.value)
            run = asyncio.ensure_future(process.post([MRI, "run"]))
            await wait_for(block, "completedSteps", lambda v: v >= 30)
            await process.post([MRI, "pause"], {"lastGoodStep": 20})
            await process.post([MRI, "pause"], {"lastGoodStep": 15})
            paused = (block.state.value, block.completedSteps.value)
            await process.post([MRI, "resume"])
            await asyncio.wait_for(run, 30)
            return armed, paused, block.state.value
        finally:
            await process.stop()

    armed, paused, state = asyncio.run(main())
    assert armed == ("Armed", 10)
    assert paused == ("Paused", 15)
    assert state == "Finished"
    uids = read_elsewhere(tmp_path / "zebra.h5")["uniqueid"]
    drops = [i for i in range(1, len(uids)) if uids[i] <= uids[i - 1]]
    assert len(drops) == 1  # one experiment before the pauses, one after
    split = drops[0]
    assert split >= 20  # at least points 10..29 came before the pause
    assert uids[:split] == list(range(11, 11 + split))  # from the point sought
    assert uids[split:] == list(range(16, M + 1))  # from the last pause's point
    assert sorted(set(uids)) == list(range(11, M + 1))


def test_abort_disarms_closes_the_file_and_a_reset_scans_again(sim, tmp_path):
    async def main():
        process = zebra_process(sim)
        await process.start()
        raw = await RawClient.open(sim)
        try:
            block = process.get_block(MRI)
            generator = gda.compound(gda.line("x", N), duration=PERIOD)
            params = {"generator": generator, "fileDir": str(tmp_path)}
            await process.post([MRI, "configure"], params)
            run = asyncio.ensure_future(process.post([MRI, "run"]))
            await wait_for(block, "completedSteps", lambda v: v >= 20)
            await process.post([MRI, "abort"])
            try:
                await run
                raise AssertionError("the run did not fail")
            except AbortedError:
                pass
            aborted = block.state.value
            status = await raw.ask("*PCAP.STATUS?")
            clock = await raw.ask("CLOCK1.ENABLE?")
            rows = read_elsewhere(tmp_path / "zebra.h5")["uniqueid"]
            await process.post([MRI, "reset"])
            ready = block.state.value
            small = gda.compound(gda.line("x", 8), duration=0.002)
            await process.post([MRI, "configure"], {**params, "generator": small})
            await process.post([MRI, "run"])
            return aborted, status, clock, rows, ready, block.state.value
        finally:
            await raw.close()
            await process.stop()

    aborted, status, clock, rows, ready, state = asyncio.run(main())
    assert aborted == "Aborted"
    assert status[0].startswith("OK =Idle")
    assert clock == ["OK =ZERO"]
    assert 20 <= len(rows) < N and rows == list(range(1, len(rows) + 1))
    assert (ready, state) == ("Ready", "Finished")
    assert read_elsewhere(tmp_path / "zebra.h5")["uniqueid"] == list(range(1, 9))

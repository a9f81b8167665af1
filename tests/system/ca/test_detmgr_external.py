"""ADCore.DetectorManager in External mode paused mid-trajectory, and scans
bigger than what it loads into the position plugin at once."""

from __future__ import annotations

import asyncio

import h5py
import numpy as np

from malcolm.config.build import build_definition
from malcolm.core import Process

from .conftest import PREFIX, run, spawn, until
from .test_detmgr_scans import (
    last_per_uid,
    line,
    make_manager,
    read_file,
    started,
)


async def build_trajectory(process: Process, start: int, stop: int, ms: int) -> None:
    """Points ``start..stop-1`` of a line as the trajectory, by PV puts.

    Every array the build reads is written: the IOC is the session's, and
    another test's trajectory (a motor manager's, with -1 indices at its
    turnarounds that trigger nothing) is still in the ones not written."""
    n = stop - start
    put = process.put
    await put(["TRAJ", "positionsA"], np.arange(start, stop, dtype=float))
    await put(["TRAJ", "positionsB"], np.zeros(n))
    await put(["TRAJ", "times"], np.full(n, ms * 1000, dtype=np.int32))  # us
    # each profile point triggers one frame, of its scan point's index
    await put(["TRAJ", "pointIndices"], np.arange(start, stop, dtype=np.int32))
    await put(["TRAJ", "numPoints"], n)
    await process.post(["TRAJ", "buildProfile"])


def test_external_pause_seek_back_rearms_at_the_point(ioc, tmp_path):
    process = make_manager("External", "TRAJ")
    total = 30

    async def scenario():
        det = await started(process)
        traj = process.get_block("TRAJ")
        try:
            params = {"generator": line(total, 0.02), "fileDir": str(tmp_path)}
            await process.post(["DET", "configure"], params)
            await build_trajectory(process, 0, total, 20)
            running = spawn(process.post(["DET", "run"]))
            moving = spawn(process.post(["TRAJ", "executeProfile"]))
            await until(lambda: det.completedSteps.value >= 12, what="12 frames")
            # the motion stops first (the motion controller's pause), then
            # the detector goes back to point 5 and waits for its trigger
            await process.post(["TRAJ", "abortProfile"])
            await asyncio.wait({moving}, timeout=5)
            assert "Failure" in str(moving.exception())  # aborted
            await process.post(["DET", "pause"], {"lastGoodStep": 5})
            assert det.state.value == "Paused" and det.completedSteps.value == 5
            drv = process.get_block("DET:DRV")
            assert drv.detectorState.value == "Acquire"  # re-armed
            assert drv.numImages.value == total - 5
            done_at_pause = traj.pointsScanned.value
            await build_trajectory(process, 5, total, 10)
            await process.post(["DET", "resume"])
            await process.post(["TRAJ", "executeProfile"])
            await asyncio.wait_for(running, 10)
            assert det.state.value == "Finished"
            return done_at_pause
        finally:
            await process.stop()

    done_at_pause = run(scenario())
    uids, pixels = read_file(str(tmp_path / "det.h5"))
    assert list(pixels) == list(uids)
    assert list(uids[:done_at_pause]) == list(range(1, done_at_pause + 1))
    assert list(uids[done_at_pause:]) == list(range(6, total + 1))
    assert sorted(last_per_uid(uids)) == list(range(1, total + 1))


def test_positions_beyond_the_preload_are_loaded_during_the_run(ioc, tmp_path):
    process = Process("detmgr-test", channels={"ca": "pyepics"})
    build_definition(
        "ADCore.DetectorManager",
        {"prefix": PREFIX, "preload": 200},
        "DET",
        process=process,
    )
    total = 2800  # more than a batch (2500) beyond the preload

    async def scenario():
        det = await started(process)
        try:
            # 200 ms of frames in the plugin when the run starts: the first
            # top-up has that long to arrive
            params = {"generator": line(total, 0.001), "fileDir": str(tmp_path)}
            await process.post(["DET", "configure"], params)
            assert process.get_block("DET:POS").positions.value == 200
            await process.post(["DET", "run"])
            assert det.state.value == "Finished"
        finally:
            await process.stop()

    run(scenario())
    uids, _ = read_file(str(tmp_path / "det.h5"))
    assert list(uids) == list(range(1, total + 1))


def test_a_10000_point_scan_is_loaded_and_armed_at_configure(ioc, tmp_path):
    process = make_manager()

    async def scenario():
        det = await started(process)
        try:
            generator = {
                **line(100, 0.001),
                "generators": [
                    {**line(100)["generators"][0], "axes": [axis]}
                    for axis in ("y", "x")
                ],
            }
            params = {"generator": generator, "fileDir": str(tmp_path)}
            await process.post(["DET", "configure"], params)
            assert det.totalSteps.value == 10000 and det.state.value == "Armed"
            pos = process.get_block("DET:POS")
            assert pos.positions.value == 10000 and pos.running.value
            assert process.get_block("DET:DRV").numImages.value == 10000
            assert process.get_block("DET:HDF").numCapture.value == 10000
            await process.post(["DET", "abort"])
        finally:
            await process.stop()

    run(scenario())


def test_batches_of_positions_sent_at_once_tag_the_frames_in_order(ioc, tmp_path):
    # 6001 positions: three XML puts sent together at configure; each frame
    # must carry its own point's position, so the batches went in in order
    process = make_manager()
    total = 6001

    async def scenario():
        det = await started(process)
        try:
            params = {"generator": line(total, 0.0005), "fileDir": str(tmp_path)}
            await process.post(["DET", "configure"], params)
            assert process.get_block("DET:POS").positions.value == total
            await process.post(["DET", "run"])
            assert det.state.value == "Finished"
        finally:
            await process.stop()

    run(scenario())
    with h5py.File(str(tmp_path / "det.h5"), "r") as f:
        points = [int(n) for n in f["entry/positions/n"][:]]
        uids = list(f["entry/uid"][:])
    assert points == list(range(total))
    assert uids == list(range(1, total + 1))

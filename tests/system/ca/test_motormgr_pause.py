"""The MotorControllerManager paused mid-run, sought back and resumed; and
aborted."""

from __future__ import annotations

import asyncio

import numpy as np
import pytest

from malcolm.core import AbortedError

from .conftest import run, spawn, until
from .motormgr import MRI, last_rows, line, manager_process, read_file


def test_pause_seek_back_and_resume_redo_the_points(ioc, tmp_path):
    process = manager_process()
    reached: list[int] = []

    async def scenario():
        await process.start()
        try:
            block = process.get_block(MRI)
            m1 = process.get_block(f"{MRI}:a")
            scan = line(100, 0.0, 5.0, duration=0.02)
            await process.post(
                [MRI, "configure"], {"generator": scan, "fileDir": str(tmp_path)}
            )
            running = spawn(process.post([MRI, "run"]))
            await until(lambda: block.completedSteps.value >= 60, 20, "60 steps")
            await process.post([MRI, "pause"], {"lastGoodStep": 30})
            assert block.state.value == "Paused"
            assert block.completedSteps.value == 30
            reached.append(
                len(read_file(str(tmp_path / "motors.h5"), ["x"])["uniqueid"])
            )
            # the motor waits at point 30's run-up: before its lower bound
            step = 5.0 / 99
            assert m1.position.value < 30 * step - step / 2
            traj = process.get_block(f"{MRI}:traj")
            assert traj.executeState.value == "Done"
            assert traj.numPoints.value == 1 + 2 * 70  # points 30..99
            await process.post([MRI, "resume"])
            await asyncio.wait_for(running, 30)
            assert block.state.value == "Finished"
            assert block.completedSteps.value == 100
            assert m1.position.value == pytest.approx(5.0 + step / 2)
        finally:
            await process.stop()

    run(scenario())
    data = read_file(str(tmp_path / "motors.h5"), ["x"])
    uid = data["uniqueid"]
    # written at the pause: the points reached before it, in order
    assert reached[0] >= 60 and list(uid[: reached[0]]) == list(
        range(1, reached[0] + 1)
    )
    # then the re-done points from 31 (point 30) on
    assert list(uid[reached[0] :]) == list(range(31, 101))
    last = last_rows(data)
    assert sorted(last) == list(range(1, 101))  # each point's last row, once
    rows = np.array([last[u] for u in range(1, 101)])
    assert np.allclose(data["x.value_set"][rows], np.linspace(0.0, 5.0, 100))
    assert np.allclose(data["x.value"][rows], data["x.value_set"][rows], atol=1e-3)


def test_abort_stops_the_trajectory_and_the_motors(ioc, tmp_path):
    process = manager_process()

    async def scenario():
        await process.start()
        try:
            block = process.get_block(MRI)
            traj = process.get_block(f"{MRI}:traj")
            scan = line(200, 0.0, 5.0, duration=0.02)
            await process.post(
                [MRI, "configure"], {"generator": scan, "fileDir": str(tmp_path)}
            )
            running = spawn(process.post([MRI, "run"]))
            await until(lambda: block.completedSteps.value >= 20, 20, "20 steps")
            await process.post([MRI, "abort"])
            assert block.state.value == "Aborted"
            with pytest.raises(AbortedError):
                await running
            assert traj.executeState.value == "Done"
            assert traj.executeStatus.value == "Failure"  # stopped short
            scanned = traj.pointsScanned.value
            await asyncio.sleep(0.2)
            assert traj.pointsScanned.value == scanned < 1 + 2 * 200
            # a new scan after reset
            await process.post([MRI, "reset"])
            await process.post([MRI, "configure"], {"generator": line(5)})
            await process.post([MRI, "run"])
            assert block.state.value == "Finished"
        finally:
            await process.stop()

    run(scenario())
    # the rows of the points reached before the abort, and the file closed
    uid = read_file(str(tmp_path / "motors.h5"), ["x"])["uniqueid"]
    assert len(uid) >= 20 and list(uid) == list(range(1, len(uid) + 1))

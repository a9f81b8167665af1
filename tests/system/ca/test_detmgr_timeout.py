"""ADCore.DetectorManager whose frames stop mid-run: the run ends in Fault
within the frame timeout, saying what is known (the frame it waited for,
the time waited, the last frame, the trigger mode, whether the driver still
acquires) and the cause only where that tells it: External triggers that
stop coming while the driver acquires (issue 13's lost trigger), or a
detector that stopped."""

from __future__ import annotations

import asyncio

import pytest

from malcolm.core import MalcolmError

from .conftest import run, spawn, until
from .test_detmgr_external import build_trajectory
from .test_detmgr_scans import line, make_manager, started


def test_external_run_whose_triggers_stop_faults_naming_the_frame(ioc, tmp_path):
    process = make_manager("External", "TRAJ")
    total = 10

    async def scenario():
        det = await started(process)
        try:
            params = {
                "generator": line(total, 0.02),
                "fileDir": str(tmp_path),
                "frameTimeout": 1.0,
            }
            await process.post(["DET", "configure"], params)
            # the motion makes the triggers of points 0..3 only: frame 5's
            # trigger never comes
            await build_trajectory(process, 0, 4, 20)
            running = spawn(process.post(["DET", "run"]))
            await process.post(["TRAJ", "executeProfile"])
            await until(lambda: det.completedSteps.value >= 4, what="4 frames")
            # a generous ceiling for "it happens": the bound is 1 s
            with pytest.raises(MalcolmError) as raised:
                await asyncio.wait_for(running, 30)
            await until(lambda: det.state.value == "Fault", what="Fault")
            health = det.health.value
            assert (
                "DET: no frame 5 (uniqueId 5) within 1 s of frame 4, the last that"
                " came (" in health
            ), health
            assert (
                "; trigger mode External; the driver is still acquiring"
                " (detectorState Acquire) and made 0 frames since: the External"
                " triggers are not arriving"
            ) in health, health
            assert "detector stopped" not in health
            assert "no frame 5" in str(raised.value)
            # the children were stopped: nothing left acquiring
            drv = process.get_block("DET:DRV")
            await until(lambda: drv.detectorState.value == "Idle", what="Idle")
            assert process.get_block("DET:HDF").capture.value is False
            await process.post(["DET", "reset"])
            assert det.state.value == "Ready"
        finally:
            await process.stop()

    run(scenario())


def test_the_default_frame_timeout_follows_the_longest_point(ioc):
    process = make_manager("External")

    async def scenario():
        det = await started(process)
        try:
            meta = det.configure.meta
            assert meta.defaults["frameTimeout"] == 0.0
            assert "3 x the longest point + 10 s" in (
                meta.takes.elements["frameTimeout"].description
            )
        finally:
            await process.stop()

    run(scenario())


def test_a_run_whose_detector_stops_says_so_not_triggers(ioc, tmp_path):
    process = make_manager("Internal")
    total = 400

    async def scenario():
        det = await started(process)
        try:
            params = {
                "generator": line(total, 0.01),
                "fileDir": str(tmp_path),
                "frameTimeout": 1.0,
            }
            await process.post(["DET", "configure"], params)
            running = spawn(process.post(["DET", "run"]))
            await until(lambda: det.completedSteps.value >= 3, what="3 frames")
            # someone stops the detector: the writer waits for frames that
            # will not come
            await process.put(["DET:DRV", "stop"], True)
            drv = process.get_block("DET:DRV")
            await until(lambda: drv.detectorState.value == "Idle", what="Idle")
            stopped_at = det.completedSteps.value
            with pytest.raises(MalcolmError) as raised:
                await asyncio.wait_for(running, 30)
            await until(lambda: det.state.value == "Fault", what="Fault")
            message = str(raised.value)
            # the writer's count (posted at most every 5 ms, as a real
            # plugin's) may bring the last frames after the driver's Idle:
            # the last frame that came is the count once the run failed
            last = det.completedSteps.value
            assert last >= stopped_at
            assert (
                f"DET: no frame {last + 1} (uniqueId {last + 1}) within 1 s of"
                f" frame {last}, the last that came (" in message
            ), message
            assert message.endswith(
                "; trigger mode Internal; the driver is not acquiring"
                " (detectorState Idle) and made 0 frames since: the detector"
                " stopped before the run's frames were taken"
            ), message
            assert "triggers" not in message
            assert message in det.health.value
            assert process.get_block("DET:HDF").capture.value is False
            await process.post(["DET", "reset"])
            assert det.state.value == "Ready"
        finally:
            await process.stop()

    run(scenario())

"""The simulated IOC at its shortest point time: a trajectory triggering the
External detector, frames into the HDF5 writer. Every point makes a frame;
the status records (progress, counters) come at a bounded rate, not one
monitor update per point, and their final values before the busy puts end.
"""

from __future__ import annotations

import asyncio

import h5py
import numpy as np

from malcolm.parts.detector_manager import MIN_EXPOSURE
from malcolm.sim.beamline_ioc.pace import MIN_PERIOD

from .conftest import follow, run, spawn, started, until

POINTS = 2000


def test_the_managers_minimum_is_the_simulations():
    assert MIN_EXPOSURE == MIN_PERIOD


def test_every_point_makes_a_frame_and_progress_comes_at_a_bounded_rate(ioc, tmp_path):
    async def scenario():
        async with started("DRV", "POS", "HDF", "TRAJ") as process:
            put = process.put
            # the trajectory: one profile point per scan point, each
            # MIN_PERIOD long, each triggering a frame
            where = np.linspace(0.0, 1.0, POINTS)
            await put(["TRAJ", "positionsA"], where)
            await put(["TRAJ", "positionsB"], -where)
            times = np.full(POINTS, round(MIN_PERIOD * 1e6), dtype=np.int32)
            await put(["TRAJ", "times"], times)
            await put(["TRAJ", "pointIndices"], np.arange(POINTS, dtype=np.int32))
            await put(["TRAJ", "numPoints"], POINTS)
            await process.post(["TRAJ", "buildProfile"])
            # the detector waits for its triggers, the plugins armed
            xml = "".join(f'<position n="{i}"/>' for i in range(POINTS))
            await put(["POS", "delete"], True)
            await put(["POS", "enableCallbacks"], True)
            await put(["POS", "idStart"], 1)
            await put(
                ["POS", "xml"], f"<pos_layout><positions>{xml}</positions></pos_layout>"
            )
            await put(["HDF", "filePath"], f"{tmp_path}/")
            await put(["HDF", "fileName"], "pace")
            await put(["HDF", "fileTemplate"], "%s%s.h5")
            await put(["HDF", "numCapture"], POINTS)
            await put(["HDF", "enableCallbacks"], True)
            await put(["HDF", "lazyOpen"], False)
            await put(["HDF", "append"], False)
            await put(["DRV", "triggerMode"], "External")
            await put(["DRV", "imageMode"], "Multiple")
            await put(["DRV", "numImages"], POINTS)
            await put(["DRV", "arrayCallbacks"], True)
            hdf, pos = process.get_block("HDF"), process.get_block("POS")
            drv, traj = process.get_block("DRV"), process.get_block("TRAJ")
            capturing = spawn(put(["HDF", "capture"], True))
            tagging = spawn(put(["POS", "start"], True))
            await until(lambda: hdf.capture.value and pos.running.value, what="armed")
            acquiring = spawn(put(["DRV", "acquire"], "Acquire"))
            await until(lambda: drv.detectorState.value == "Acquire", what="acquiring")
            scanned = follow(process, "TRAJ", "pointsScanned")
            captured = follow(process, "HDF", "numCaptured")
            frames = follow(process, "DRV", "numImagesCounter")
            await process.post(["TRAJ", "executeProfile"])  # returns at the end
            await asyncio.gather(acquiring, capturing, tagging)
            # the final counts are there when the puts return
            assert traj.pointsScanned.value == POINTS
            assert drv.numImagesCounter.value == POINTS
            assert hdf.numCaptured.value == POINTS
            assert pos.processed.value == POINTS and pos.positions.value == 0
            assert hdf.writeStatus.value == "Write OK"
            # each counter only went up, to the end, in fewer updates than
            # points (a status poll, not a post per point)
            for seen in (scanned, captured, frames):
                counts = [c for c in seen[1:] if c]  # [0]: the value before
                assert counts == sorted(counts) and counts[-1] == POINTS
                assert len(counts) < POINTS, len(counts)
            # the controller's record of where the motors were at each point
            assert list(traj.readbacksA.value) == list(where)
            assert traj.executeStatus.value == "Success"
            await put(["DRV", "triggerMode"], "Internal")
            await put(["DRV", "imageMode"], "Single")
            return hdf.fullFileName.value

    filename = run(scenario())
    with h5py.File(filename, "r") as f:
        uids = list(f["entry/uid"][:])
        assert uids == list(range(1, POINTS + 1))  # every point, in order
        assert list(f["entry/positions/n"][:]) == list(range(POINTS))
        assert f["entry/data"][POINTS - 1][0][0] == POINTS

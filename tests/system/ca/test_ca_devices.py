"""The simulated devices through their blocks: trajectory, HDF5 writer,
position plugin."""

from __future__ import annotations

import asyncio

import h5py
import numpy as np
import pytest

from malcolm.io import ChannelError

from .conftest import follow, run, spawn, started, until


def test_a_trajectory_is_built_and_executed_in_time(ioc):
    async def scenario():
        async with started("TRAJ", "M1", "M2") as process:
            traj = process.get_block("TRAJ")
            put = process.put
            await put(["TRAJ", "positionsA"], np.array([1.0, 2.0, 3.0, 4.0]))
            await put(["TRAJ", "positionsB"], np.array([-1.0, -2.0, -3.0, -4.0]))
            await put(["TRAJ", "times"], np.array([0, 5, 5, 5], dtype=np.int32))
            await put(["TRAJ", "pointIndices"], np.arange(4, dtype=np.int32))
            await put(["TRAJ", "numPoints"], 4)
            # a time of 0 us: the build fails, and says why
            with pytest.raises(ChannelError) as info:
                await process.post(["TRAJ", "buildProfile"])
            message = str(info.value)
            assert message.startswith("TRAJ.buildProfile: ")
            assert "'Failure'" in message and "every time must be positive" in message
            assert traj.buildStatus.value == "Failure"
            times = np.array([20, 20, 20, 20], dtype=np.int32) * 1000  # us
            await put(["TRAJ", "times"], times)
            await process.post(["TRAJ", "buildProfile"])
            assert traj.buildStatus.value == "Success"
            scanned = follow(process, "TRAJ", "pointsScanned")
            await process.post(["TRAJ", "executeProfile"])  # returns at the end
            assert traj.pointsScanned.value == 4
            # after the value it had when followed (an earlier module's
            # execution may have left it at its last count): 0, then each point
            assert [p for p in scanned[1:] if p] == [1, 2, 3, 4]
            assert traj.executeStatus.value == "Success"
            assert traj.executeState.value == "Done"
            m1, m2 = process.get_block("M1"), process.get_block("M2")
            assert (m1.position.value, m2.position.value) == (4.0, -4.0)

    run(scenario())


def test_the_hdf_writer_writes_tagged_frames_into_a_file(ioc, tmp_path):
    async def scenario():
        async with started("DRV", "POS", "HDF") as process:
            put = process.put
            xml = "".join(f'<position x="{i * 0.5}"/>' for i in range(6))
            await put(["POS", "delete"], True)
            await put(["POS", "enableCallbacks"], True)
            await put(
                ["POS", "xml"], f"<pos_layout><positions>{xml}</positions></pos_layout>"
            )
            pos = process.get_block("POS")
            assert pos.positions.value == 6
            await put(["HDF", "filePath"], f"{tmp_path}/")
            await put(["HDF", "fileName"], "scan1")
            await put(["HDF", "fileTemplate"], "%s%s.h5")
            await put(["HDF", "numCapture"], 6)
            await put(["HDF", "enableCallbacks"], True)
            await put(["DRV", "exposure"], 0.005)
            # the session's IOC may hold another test's External mode
            await put(["DRV", "triggerMode"], "Internal")
            await put(["DRV", "numImages"], 6)
            await put(["DRV", "imageMode"], "Multiple")
            # completes at 6 frames / when the positions are used up
            capturing = spawn(put(["HDF", "capture"], True))
            starting = spawn(put(["POS", "start"], True))
            hdf = process.get_block("HDF")
            await until(lambda: hdf.capture.value and pos.running.value, what="armed")
            await put(["DRV", "acquire"], "Acquire")
            await asyncio.gather(capturing, starting)
            assert hdf.numCaptured.value == 6 and pos.positions.value == 0
            assert pos.processed.value == 6
            assert hdf.writeStatus.value == "Write OK"
            assert hdf.fullFileName.value == f"{tmp_path}/scan1.h5"
            await put(["DRV", "imageMode"], "Single")
            return hdf.fullFileName.value

    filename = run(scenario())
    with h5py.File(filename, "r") as f:
        assert f["entry/data"].shape == (6, 8, 8)
        assert list(f["entry/positions/x"][:]) == [0.0, 0.5, 1.0, 1.5, 2.0, 2.5]
        uids = list(f["entry/uid"][:])
        assert uids == list(range(uids[0], uids[0] + 6))
        assert f["entry/data"][0][0][0] == uids[0]


def test_a_file_that_cannot_be_opened_is_reported(ioc, tmp_path):
    async def scenario():
        async with started("HDF") as process:
            await process.put(["HDF", "filePath"], f"{tmp_path}/no/such/dir/")
            await process.put(["HDF", "fileName"], "x")
            # the file opened at Capture, whatever an earlier test left (a
            # manager's resumed run leaves LazyOpen on: the capture then
            # waited for a first frame that never came)
            await process.put(["HDF", "lazyOpen"], False)
            await process.put(["HDF", "capture"], True)
            hdf = process.get_block("HDF")
            assert hdf.writeStatus.value == "Write error"
            assert "cannot open" in hdf.writeMessage.value
            assert hdf.capture.value is False

    run(scenario())

"""ADCore.DetectorManager on the simulated IOC: scans into a real HDF5 file.

Internal triggering (a line, a 2-D grid run a row at a time), External
triggering by the trajectory scan driven with PV puts, pause/seek/resume and
abort; every test reads the file the IOC wrote.
"""

from __future__ import annotations

import asyncio
from typing import Any

import h5py
import numpy as np
import pytest

from malcolm.config.build import build_definition
from malcolm.core import Process

from .conftest import BLOCKS, PREFIX, run, spawn, until


def line(size: int, duration: float = 0.002) -> dict[str, Any]:
    return grid(0, size, duration)


def grid(ny: int, nx: int, duration: float = 0.002) -> dict[str, Any]:
    """A CompoundGenerator as GDA sends it: y outer (if ny), x inner snaking."""

    def axis(name: str, size: int, snake: bool) -> dict[str, Any]:
        return {
            "typeid": "scanpointgenerator:generator/LineGenerator:1.0",
            "axes": [name],
            "units": ["mm"],
            "start": [0.0],
            "stop": [1.0],
            "size": size,
            "alternate": snake,
        }

    generators = ([axis("y", ny, False)] if ny else []) + [axis("x", nx, bool(ny))]
    return {
        "typeid": "scanpointgenerator:generator/CompoundGenerator:1.0",
        "generators": generators,
        "excluders": [],
        "mutators": [],
        "duration": duration,
    }


def make_manager(trigger_mode: str = "Internal", *extra: str) -> Process:
    """A process with the manager DET over the IOC (and hardware ``extra``)."""
    process = Process("detmgr-test", channels={"ca": "pyepics"})
    build_definition(
        "ADCore.DetectorManager",
        {"prefix": PREFIX, "triggerMode": trigger_mode},
        "DET",
        process=process,
    )
    for mri in extra:
        name, values = BLOCKS[mri]
        build_definition(name, values, mri, process=process)
    return process


def read_file(filename: str) -> tuple[np.ndarray, np.ndarray]:
    """(uniqueIds, first pixel of each frame) of a closed file: h5py cannot
    open a file another process still has open for writing."""
    with h5py.File(filename, "r") as f:
        return f["entry/uid"][:], f["entry/data"][:, 0, 0]


def last_per_uid(uids: np.ndarray) -> dict[int, int]:
    """uniqueId -> row of its last frame (what the assembler keeps)."""
    return {int(u): i for i, u in enumerate(uids)}


async def started(process: Process) -> Any:
    await process.start()
    det = process.get_block("DET")
    assert det.state.value == "Ready", det.health.value
    return det


def test_a_line_internal_fills_datasets_and_a_closed_file(ioc, tmp_path):
    process = make_manager()

    async def scenario():
        det = await started(process)
        try:
            params = {"generator": line(7), "fileDir": str(tmp_path)}
            await process.post(["DET", "configure"], params)
            assert det.state.value == "Armed"
            drv = process.get_block("DET:DRV")
            assert drv.triggerMode.value == "Internal"
            assert drv.imageMode.value == "Multiple" and drv.numImages.value == 7
            assert drv.exposure.value == pytest.approx(0.002)
            pos = process.get_block("DET:POS")
            assert pos.running.value and pos.positions.value == 7
            assert pos.idStart.value == 1
            assert process.get_block("DET:HDF").capture.value is True
            datasets = det.datasets.value
            assert datasets["name"] == ("det.data",)
            assert datasets["filename"] == ("det.h5",)
            assert datasets["type"] == ("primary",)
            assert datasets["rank"] == (2,)
            assert datasets["path"] == ("/entry/data",)
            assert datasets["uniqueid"] == ("/entry/uid",)
            progress: list[int] = []
            process.subscribe(
                ["DET", "completedSteps", "value"],
                lambda d: progress.append(d[-1][1]),
            )
            await process.post(["DET", "run"])
            assert det.state.value == "Finished"
            assert det.completedSteps.value == 7
            assert progress == sorted(progress) and progress[-1] == 7
        finally:
            await process.stop()

    run(scenario())
    uids, pixels = read_file(str(tmp_path / "det.h5"))
    assert list(uids) == [1, 2, 3, 4, 5, 6, 7]  # point index + 1
    assert list(pixels) == list(uids)  # each frame is the one tagged
    with h5py.File(tmp_path / "det.h5", "r") as f:
        assert list(f["entry/positions/n"][:]) == [0, 1, 2, 3, 4, 5, 6]


def test_a_grid_run_a_row_at_a_time_appends_each_run(ioc, tmp_path):
    process = make_manager()

    async def scenario():
        det = await started(process)
        try:
            params = {
                "generator": grid(3, 4),
                "axesToMove": ["x"],
                "fileDir": str(tmp_path),
                "formatName": "grid",
            }
            await process.post(["DET", "configure"], params)
            steps = []
            while det.state.value == "Armed":
                await process.post(["DET", "run"])
                steps.append(det.completedSteps.value)
            assert steps == [4, 8, 12] and det.state.value == "Finished"
        finally:
            await process.stop()

    run(scenario())
    uids, pixels = read_file(str(tmp_path / "grid.h5"))
    assert list(uids) == list(range(1, 13)) and list(pixels) == list(uids)


def test_external_frames_come_from_the_trajectory(ioc, tmp_path):
    process = make_manager("External", "TRAJ")

    async def scenario():
        det = await started(process)
        try:
            params = {"generator": line(6, 0.01), "fileDir": str(tmp_path)}
            await process.post(["DET", "configure"], params)
            drv = process.get_block("DET:DRV")
            # armed: acquiring, waiting for triggers, before any motion
            assert drv.triggerMode.value == "External"
            assert drv.detectorState.value == "Acquire"
            await asyncio.sleep(0.1)
            assert drv.numImagesCounter.value == 0  # nothing without triggers
            put = process.put
            await put(["TRAJ", "positionsA"], np.linspace(0.0, 1.0, 6))
            await put(["TRAJ", "positionsB"], np.zeros(6))
            await put(["TRAJ", "times"], np.full(6, 10_000, dtype=np.int32))
            # every array the build reads: the session's IOC keeps another
            # test's (a motor manager's -1 indices trigger nothing)
            await put(["TRAJ", "pointIndices"], np.arange(6, dtype=np.int32))
            await put(["TRAJ", "numPoints"], 6)
            await process.post(["TRAJ", "buildProfile"])
            running = spawn(process.post(["DET", "run"]))
            await process.post(["TRAJ", "executeProfile"])
            await asyncio.wait_for(running, 10)
            assert det.state.value == "Finished" and det.completedSteps.value == 6
        finally:
            await process.stop()

    run(scenario())
    uids, pixels = read_file(str(tmp_path / "det.h5"))
    assert list(uids) == [1, 2, 3, 4, 5, 6] and list(pixels) == list(uids)


def test_pause_seek_back_and_resume_give_one_frame_per_point(ioc, tmp_path):
    process = make_manager()
    # 85 frames (0.85 s) left when the pause is asked for at 15: 25 (0.25 s)
    # was a small margin for a loaded 2-core machine
    total = 100

    async def scenario():
        det = await started(process)
        try:
            params = {"generator": line(total, 0.01), "fileDir": str(tmp_path)}
            await process.post(["DET", "configure"], params)
            running = spawn(process.post(["DET", "run"]))
            await until(lambda: det.completedSteps.value >= 15, what="15 frames")
            await process.post(["DET", "pause"], {"lastGoodStep": 8})
            assert det.state.value == "Paused" and det.completedSteps.value == 8
            pos = process.get_block("DET:POS")
            assert pos.idStart.value == 9  # the next frame is point 8
            assert pos.positions.value == total - 8
            # the file is closed while paused: another process can read it
            paused_uids, _ = read_file(str(tmp_path / "det.h5"))
            assert len(paused_uids) >= 15
            await process.post(["DET", "resume"])
            await asyncio.wait_for(running, 20)
            assert det.state.value == "Finished"
            assert det.completedSteps.value == total
            return len(paused_uids)
        finally:
            await process.stop()

    before = run(scenario())
    uids, pixels = read_file(str(tmp_path / "det.h5"))
    assert list(pixels) == list(uids)
    # rows in the order taken: 1.. up to the pause, then 9..40 again
    assert list(uids[:before]) == list(range(1, before + 1))
    assert list(uids[before:]) == list(range(9, total + 1))
    kept = last_per_uid(uids)
    assert sorted(kept) == list(range(1, total + 1))  # one frame per point


def test_abort_stops_and_closes_the_file_and_reset_scans_again(ioc, tmp_path):
    process = make_manager()

    async def scenario():
        det = await started(process)
        try:
            params = {"generator": line(200, 0.01), "fileDir": str(tmp_path)}
            await process.post(["DET", "configure"], params)
            running = spawn(process.post(["DET", "run"]))
            await until(lambda: det.completedSteps.value >= 3, what="3 frames")
            await process.post(["DET", "abort"])
            assert det.state.value == "Aborted"
            with pytest.raises(Exception, match="abort"):
                await asyncio.wait_for(running, 5)
            drv = process.get_block("DET:DRV")
            assert drv.detectorState.value == "Idle"
            assert process.get_block("DET:HDF").capture.value is False
            assert process.get_block("DET:POS").running.value is False
            uids, _ = read_file(str(tmp_path / "det.h5"))  # closed
            assert 3 <= len(uids) < 200
            await process.post(["DET", "reset"])
            assert det.state.value == "Ready"
            params = {"generator": line(3), "fileDir": str(tmp_path)}
            await process.post(["DET", "configure"], params)
            await process.post(["DET", "run"])
            assert det.state.value == "Finished"
        finally:
            await process.stop()

    run(scenario())
    uids, _ = read_file(str(tmp_path / "det.h5"))
    assert list(uids) == [1, 2, 3]  # a new scan makes a new file


def test_bad_arguments_are_refused_naming_them(ioc, tmp_path):
    process = make_manager()

    async def scenario():
        det = await started(process)
        try:
            with pytest.raises(Exception, match="DET.configure.fileDir"):
                await process.post(
                    ["DET", "configure"], {"generator": line(3), "fileDir": "rel"}
                )
            assert det.state.value == "Ready"
            bad = {"generator": line(3), "fileDir": str(tmp_path / "missing")}
            with pytest.raises(Exception, match="cannot write"):
                await process.post(["DET", "configure"], bad)
            assert det.state.value == "Fault"
            await process.post(["DET", "reset"])
            assert det.state.value == "Ready"
        finally:
            await process.stop()

    run(scenario())


def test_no_file_dir_runs_without_a_file_and_disable_stops_the_hardware(ioc):
    process = make_manager()

    async def scenario():
        det = await started(process)
        try:
            await process.post(["DET", "configure"], {"generator": line(5)})
            assert det.datasets.value["name"] == ()  # no file, no datasets
            hdf = process.get_block("DET:HDF")
            assert hdf.capture.value is False and hdf.enableCallbacks.value is False
            await process.post(["DET", "run"])
            assert det.state.value == "Finished" and det.completedSteps.value == 5
            # armed External, then disabled: nothing is left waiting
            await process.put(["DET", "triggerMode"], "External")
            await process.post(["DET", "configure"], {"generator": line(5)})
            drv = process.get_block("DET:DRV")
            assert drv.detectorState.value == "Acquire"
            await process.post(["DET", "disable"])
            assert det.state.value == "Disabled"
            assert drv.detectorState.value == "Idle"
            assert process.get_block("DET:POS").running.value is False
            await process.post(["DET", "reset"])
            assert det.state.value == "Ready"
        finally:
            await process.stop()

    run(scenario())


def test_validate_raises_a_duration_under_the_detectors_shortest_frame(ioc):
    """As a detector's readout time: the simulation cannot keep pace below
    MIN_EXPOSURE (malcolm.sim.beamline_ioc.pace), so validate gives it back."""
    from scanspec.specs import ConstantDuration, Line

    from malcolm.core import MalcolmError
    from malcolm.parts.detector_manager import MIN_EXPOSURE

    process = make_manager("External", "DRV")

    async def scenario():
        det = await started(process)
        try:
            short = line(5, MIN_EXPOSURE / 10)
            validated = await process.post(["DET", "validate"], {"generator": short})
            assert validated["generator"]["duration"] == MIN_EXPOSURE
            assert validated["generator"]["generators"] == short["generators"]
            # long enough: given back as it was; an exposure too short raised
            fine = line(5, 0.002)
            validated = await process.post(
                ["DET", "validate"], {"generator": fine, "exposure": 1e-6}
            )
            assert validated["generator"] == fine
            assert validated["exposure"] == MIN_EXPOSURE
            assert det.state.value == "Ready"  # validate changed nothing
            # a scanspec Spec cannot be given back changed: refused, naming why
            spec = ConstantDuration(MIN_EXPOSURE / 10, Line("x", 0, 1, 5))
            with pytest.raises(MalcolmError, match="shortest frame, 0.0001 s"):
                await process.post(["DET", "validate"], {"generator": spec})
            # configure takes the validated duration: the driver's exposure
            await process.post(["DET", "configure"], {"generator": short})
            drv = process.get_block("DET:DRV")
            assert drv.exposure.value == pytest.approx(MIN_EXPOSURE)
            await process.post(["DET", "abort"])
        finally:
            await process.stop()

    run(scenario())

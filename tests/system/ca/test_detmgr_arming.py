"""ADCore.DetectorManager's arming on the simulated IOC: the writer's chain
(settings, capture) and the plugin's (clear, load, start) go at once; a
writer that cannot open its file fails the configure with the plugin's
chain ended too, and the next configure arms both."""

from __future__ import annotations

import h5py

from malcolm.parts.detector_manager import DetectorManagerPart

from .conftest import run
from .test_detmgr_scans import line, make_manager, started


def manager_part(process) -> DetectorManagerPart:
    """The DET block's DetectorManagerPart."""
    return next(
        p
        for p in process.get_controller("DET").parts.values()
        if isinstance(p, DetectorManagerPart)
    )


def test_a_writer_failure_ends_both_chains_and_the_next_configure_arms(ioc, tmp_path):
    process = make_manager()

    async def scenario():
        det = await started(process)
        part = manager_part(process)
        try:
            bad = {"generator": line(5), "fileDir": str(tmp_path / "missing")}
            try:
                await process.post(["DET", "configure"], bad)
            except Exception as e:
                assert "cannot write" in str(e)
            else:
                raise AssertionError("a missing fileDir was taken")
            assert det.state.value == "Fault"
            await process.post(["DET", "reset"])
            assert det.state.value == "Ready"
            assert not part.pos.running.value and not part.hdf.capture.value
            good = {"generator": line(5), "fileDir": str(tmp_path),
                    "formatName": "armed"}  # fmt: skip
            await process.post(["DET", "configure"], good)
            assert det.state.value == "Armed"
            # both armed, the plugin holding all five positions, the file made
            assert part.pos.running.value and part.hdf.capture.value
            assert part.pos.positions.value == 5
            await process.post(["DET", "run"])
            assert det.state.value == "Finished"
            with h5py.File(tmp_path / "armed.h5", "r") as f:
                assert list(f["entry/uid"][:]) == [1, 2, 3, 4, 5]
        finally:
            await process.stop()

    run(scenario())


def test_the_plugin_is_cleared_before_the_positions_sent_with_it_load(ioc, tmp_path):
    # the clearing and the XML go at once: the plugin holds each configure's
    # positions alone (not 5 + 7, nor none), and the frames get their ids
    process = make_manager()

    async def scenario():
        det = await started(process)
        part = manager_part(process)
        try:
            for points in (5, 7, 3):
                params = {"generator": line(points), "fileDir": str(tmp_path),
                          "formatName": f"cleared{points}"}  # fmt: skip
                await process.post(["DET", "configure"], params)
                assert det.state.value == "Armed"
                assert part.pos.positions.value == points
                if points != 3:
                    await process.post(["DET", "reset"])
            await process.post(["DET", "run"])
            assert det.state.value == "Finished"
            with h5py.File(tmp_path / "cleared3.h5", "r") as f:
                assert list(f["entry/uid"][:]) == [1, 2, 3]
        finally:
            await process.stop()

    run(scenario())

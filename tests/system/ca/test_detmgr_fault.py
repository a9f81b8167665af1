"""ADCore.DetectorManager when its IOC dies mid-run, and after it is back."""

from __future__ import annotations

import asyncio

import pytest

from malcolm.core import MalcolmError

from .conftest import PREFIX, run, spawn, until
from .test_detmgr_scans import line, make_manager, read_file, started

#: seconds within which a lost IOC shows, and a restarted one is back
LOST_WITHIN = 5.0
BACK_WITHIN = 60.0


def test_a_killed_ioc_faults_the_run_naming_it_and_reset_recovers(ioc, tmp_path):
    process = make_manager()

    async def scenario():
        det = await started(process)
        try:
            params = {"generator": line(500, 0.01), "fileDir": str(tmp_path)}
            await process.post(["DET", "configure"], params)
            running = spawn(process.post(["DET", "run"]))
            await until(lambda: det.completedSteps.value >= 3, what="3 frames")

            ioc.kill()
            # the run fails promptly, it does not wait for frames forever
            with pytest.raises(MalcolmError) as info:
                await asyncio.wait_for(running, LOST_WITHIN)
            assert det.state.value == "Fault"
            health = det.health.value
            assert f"{PREFIX}:" in health and "connection lost" in health, health
            assert "DET:" in health, health  # the child that lost it
            assert str(info.value)
            # reset while the IOC is away: refused, naming what is missing
            with pytest.raises(MalcolmError, match="not connected"):
                await process.post(["DET", "reset"])
            assert det.state.value == "Fault"

            ioc.start()
            children = [process.get_block(f"DET:{c}") for c in ("DRV", "POS", "HDF")]
            await until(
                lambda: all(c.health.value == "OK" for c in children),
                BACK_WITHIN,
                "the children back after the IOC restarted",
            )
            await process.post(["DET", "reset"])
            assert det.state.value == "Ready" and det.health.value == "OK"
            params = {"generator": line(5), "fileDir": str(tmp_path)}
            await process.post(["DET", "configure"], params)
            await process.post(["DET", "run"])
            assert det.state.value == "Finished"
        finally:
            await process.stop()

    run(scenario(), timeout=150)
    uids, _ = read_file(str(tmp_path / "det.h5"))
    assert list(uids) == [1, 2, 3, 4, 5]

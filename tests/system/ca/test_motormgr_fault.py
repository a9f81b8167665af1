"""The MotorControllerManager loses its IOC mid-run: Fault naming what was
lost, promptly; reset once the IOC is back gives Ready and a scan runs."""

from __future__ import annotations

import asyncio

import pytest

from malcolm.core import MalcolmError

from .conftest import PREFIX, run, spawn, until
from .motormgr import MRI, line, manager_process

#: seconds within which a lost IOC shows, and a restarted one is back
LOST_WITHIN = 5.0
BACK_WITHIN = 60.0


def test_the_ioc_killed_mid_run_faults_and_reset_recovers(ioc, tmp_path):
    process = manager_process()

    async def scenario():
        await process.start()
        try:
            block = process.get_block(MRI)
            scan = line(500, 0.0, 5.0, duration=0.02)  # 10 s
            await process.post(
                [MRI, "configure"], {"generator": scan, "fileDir": str(tmp_path)}
            )
            running = spawn(process.post([MRI, "run"]))
            await until(lambda: block.completedSteps.value >= 10, 20, "10 steps")
            ioc.kill()
            with pytest.raises(MalcolmError) as info:
                await asyncio.wait_for(running, LOST_WITHIN)  # never a hang
            assert block.state.value == "Fault"
            health = block.health.value
            assert f"lost connection to {MRI}:traj" in health, health
            assert f"{PREFIX}:TRAJ:ExecuteProfile" in health, health
            assert "disconnect" in health, health
            assert str(info.value) == health
            # reset while the IOC is away: refused, naming what is missing
            with pytest.raises(MalcolmError, match=f"{MRI}:traj: "):
                await process.post([MRI, "reset"])
            assert block.state.value == "Fault"

            ioc.start()
            children = [process.get_block(f"{MRI}:{c}") for c in ("traj", "a", "b")]
            await until(
                lambda: all(c.health.value == "OK" for c in children),
                BACK_WITHIN,
                "the children connected again",
            )
            await process.post([MRI, "reset"])
            assert block.state.value == "Ready"
            assert block.health.value == "OK"
            await process.post([MRI, "configure"], {"generator": line(10)})
            await process.post([MRI, "run"])
            assert block.state.value == "Finished"
        finally:
            await process.stop()

    run(scenario(), timeout=150)

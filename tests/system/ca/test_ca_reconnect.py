"""Killing the IOC and starting it again, under live hardware blocks."""

from __future__ import annotations

import asyncio

import pytest

from malcolm.core import AlarmSeverity, AlarmStatus
from malcolm.io import DisconnectedError

from .conftest import run, spawn, started, until

#: seconds within which a lost IOC shows, and a restarted one is back
LOST_WITHIN = 5.0
BACK_WITHIN = 60.0


def test_killing_the_ioc_invalidates_and_restarting_recovers(ioc):
    async def scenario():
        async with started("DRV", "M1") as process:
            drv = process.get_block("DRV")
            await process.put(["DRV", "exposure"], 0.5)
            assert drv.health.value == "OK"
            m1 = process.get_block("M1")
            # a move of 5 s at 10 mm/s: its put is in flight when the IOC dies
            moving = spawn(process.put(["M1", "position"], 50.0))
            await until(lambda: m1.doneMoving.value is False, what="M1 moving")

            ioc.kill()
            took = await until(
                lambda: (
                    drv.exposure.alarm.severity is AlarmSeverity.INVALID_ALARM
                    and drv.health.value != "OK"
                ),
                LOST_WITHIN,
                "INVALID alarm and health after the IOC died",
            )
            assert took < LOST_WITHIN
            alarm = drv.exposure.alarm
            assert alarm.status is AlarmStatus.CLIENT_STATUS
            assert "connection lost" in alarm.message
            assert "CATEST:CAM" in drv.health.value
            for name in ("numImages", "imageMode", "manufacturer", "xml"):
                assert drv[name].alarm.severity is AlarmSeverity.INVALID_ALARM
            assert drv.state.value == "Ready"  # the state is left as it was
            await until(lambda: m1.health.value != "OK", LOST_WITHIN, "M1 health")
            # the put in flight fails (naming block and field), it does not hang
            with pytest.raises(DisconnectedError, match="M1.position: "):
                await asyncio.wait_for(moving, LOST_WITHIN)
            # a caller is never hung: a put fails at once, naming the PV
            with pytest.raises(DisconnectedError, match="CATEST:CAM:Exposure"):
                await asyncio.wait_for(process.put(["DRV", "exposure"], 0.2), 2)
            with pytest.raises(DisconnectedError):
                await asyncio.wait_for(process.post(["M1", "stop"]), 2)
            assert drv.exposure.value == 0.5  # the last value is kept

            ioc.start()  # the same IOC again: the same blocks recover
            await until(
                lambda: drv.health.value == "OK" and m1.health.value == "OK",
                BACK_WITHIN,
                "health OK after the IOC came back",
            )
            assert drv.exposure.alarm.severity is AlarmSeverity.NO_ALARM
            assert drv.exposure.value == 0.1  # what the new IOC holds
            await process.put(["DRV", "exposure"], 0.3)
            assert drv.exposure.value == 0.3
            assert process.get_block("DRV") is drv

    run(scenario(), timeout=120)


def test_a_block_started_without_its_ioc_connects_when_it_appears(sim_ioc):
    sim_ioc.kill()

    async def scenario():
        async with started("M2") as process:
            m2 = process.get_block("M2")
            # Reset waited CONNECT_TIMEOUT and went on: the block is usable
            assert m2.state.value == "Ready"
            assert "not connected yet" in m2.health.value
            assert m2.position.alarm.severity is AlarmSeverity.INVALID_ALARM
            sim_ioc.start()
            await until(lambda: m2.health.value == "OK", BACK_WITHIN, "M2 health")
            assert m2.doneMoving.value is True

    run(scenario(), timeout=120)


def test_a_block_started_without_its_ioc_takes_its_labels_and_units(sim_ioc):
    # the meta the definition leaves open (an enum's labels, a number's
    # units, precision and limits) comes from the IOC when it appears, not
    # only when it answers within Reset's wait
    sim_ioc.kill()

    async def scenario():
        async with started("DRV") as process:
            drv = process.get_block("DRV")
            assert "not connected yet" in drv.health.value
            sim_ioc.start()
            await until(lambda: drv.health.value == "OK", BACK_WITHIN, "DRV health")
            await until(
                lambda: drv.imageMode.meta.choices != ("0", "1"),
                LOST_WITHIN,
                "the IOC's labels for imageMode",
            )
            assert drv.imageMode.meta.choices == ("Single", "Multiple", "Continuous")
            assert drv.imageMode.value == "Single"
            display = drv.exposure.meta.display
            assert (display["units"], display["precision"]) == ("s", 4)
            assert (display["limitLow"], display["limitHigh"]) == (0.0, 100.0)
            await process.put(["DRV", "imageMode"], "Multiple")
            assert drv.imageMode.value == "Multiple"
            await process.put(["DRV", "imageMode"], "Single")

    run(scenario(), timeout=120)

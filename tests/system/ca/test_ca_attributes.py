"""Hardware blocks from the YAML definitions, against the simulated IOC."""

from __future__ import annotations

import epics
import numpy as np
import pytest

from malcolm.core import (
    AlarmSeverity,
    BadValueError,
    ChoiceMeta,
    NumberArrayMeta,
    NumberMeta,
)

from .conftest import PREFIX, follow, run, spawn, started, until


def test_every_attribute_type_is_read_from_the_ioc(fresh_ioc):
    async def scenario():
        async with started() as process:
            for mri in ("DRV", "POS", "HDF", "M1", "M2", "TRAJ"):
                block = process.get_block(mri)
                assert block.health.value == "OK", (mri, block.health.value)
                assert block.state.value == "Ready"
            drv = process.get_block("DRV")
            # ca.Double, with units, precision and limits from the PV
            assert drv.exposure.value == 0.1
            assert drv.exposure.alarm.severity is AlarmSeverity.NO_ALARM
            assert drv.exposure.timeStamp.secondsPastEpoch > 0
            display = drv.exposure.meta.display
            assert (display["units"], display["precision"]) == ("s", 4)
            assert (display["limitLow"], display["limitHigh"]) == (0.0, 100.0)
            # ca.Long, ca.String, ca.LongString, ca.Bool, ca.Enum
            assert drv.numImages.value == 1 and isinstance(
                drv.numImages.meta, NumberMeta
            )
            assert drv.manufacturer.value == "Simulated Detector"
            assert drv.xml.value == ""
            assert drv.arrayCallbacks.value is True
            assert drv.imageMode.value == "Single"
            assert isinstance(drv.imageMode.meta, ChoiceMeta)
            assert drv.imageMode.meta.choices == ("Single", "Multiple", "Continuous")
            assert drv.acquire.meta.choices == ("Done", "Acquire")  # no choices given
            assert drv.detectorState.value == "Idle"
            # ca.DoubleArray, ca.LongArray
            traj = process.get_block("TRAJ")
            assert isinstance(traj.positionsA.meta, NumberArrayMeta)
            assert traj.positionsA.meta.dtype == "float64"
            assert len(traj.positionsA.value) == 50_000  # the waveform's NELM
            assert traj.times.meta.dtype == "int32"
            assert traj.times.meta.display["units"] == "us"
            # ca.Action: a method
            assert "buildProfile" in traj and "stop" in process.get_block("M1")
            # the motor's limits are VAL's drive limits
            m1 = process.get_block("M1")
            assert m1.position.meta.display["limitLow"] == -100.0
            assert m1.position.meta.display["limitHigh"] == 100.0
            assert m1.doneMoving.value is True

    run(scenario())


def test_a_put_completes_and_shows_the_readback(ioc):
    async def scenario():
        async with started("DRV", "HDF", "TRAJ") as process:
            drv = process.get_block("DRV")
            await process.put(["DRV", "exposure"], 0.25)
            assert drv.exposure.value == 0.25  # the readback, read after the put
            await process.put(["DRV", "imageMode"], "Multiple")
            assert drv.imageMode.value == "Multiple"
            await process.put(["DRV", "arrayCallbacks"], False)
            assert drv.arrayCallbacks.value is False
            await process.put(["DRV", "arrayCallbacks"], True)
            xml = "<pos_layout>" + "x" * 5000 + "</pos_layout>"
            await process.put(["DRV", "xml"], xml)
            assert drv.xml.value == xml
            await process.put(["HDF", "fileTemplate"], "%s%s_x.h5")
            assert process.get_block("HDF").fileTemplate.value == "%s%s_x.h5"
            await process.put(["HDF", "fileTemplate"], "%s%s.h5")
            await process.put(["TRAJ", "positionsA"], np.array([1.5, 2.5, 3.5]))
            traj = process.get_block("TRAJ")
            assert list(traj.positionsA.value[:3]) == [1.5, 2.5, 3.5]
            await process.put(["TRAJ", "times"], np.array([10, 20], dtype=np.int32))
            assert list(traj.times.value[:2]) == [10, 20]
            # what another CA client sees: the IOC has it
            assert epics.caget(f"{PREFIX}:CAM:Exposure_RBV", use_monitor=False) == 0.25
            await process.put(["DRV", "imageMode"], "Single")

    run(scenario())


def test_monitors_follow_changes_made_by_the_ioc(fresh_ioc):
    async def scenario():
        async with started("DRV", "M1") as process:
            drv = process.get_block("DRV")
            await process.put(["DRV", "exposure"], 0.01)
            await process.put(["DRV", "numImages"], 5)
            await process.put(["DRV", "imageMode"], "Multiple")
            counters = follow(process, "DRV", "numImagesCounter")
            before = drv.arrayCounter.value
            await process.put(["DRV", "acquire"], "Acquire")  # completes at the end
            assert drv.numImagesCounter.value == 5
            assert drv.arrayCounter.value == before + 5
            assert [1, 2, 3, 4, 5] == [c for c in counters if c][-5:]
            # a motor move: the readback monitor shows it moving
            m1 = process.get_block("M1")
            await process.put(["M1", "velocity"], 20.0)
            positions = follow(process, "M1", "position")
            done = follow(process, "M1", "doneMoving")
            await process.put(["M1", "position"], 2.0)  # completes when still
            assert m1.position.value == 2.0 and m1.doneMoving.value is True
            assert any(0.0 < p < 2.0 for p in positions), positions
            assert False in done
            await process.put(["M1", "position"], 0.0)
            await process.put(["DRV", "imageMode"], "Single")

    run(scenario())


@pytest.mark.parametrize(
    "field, value, why",
    [
        ("exposure", "abc", "expected a number"),
        ("exposure", 1000.0, "outside the limits [0.0, 100.0]"),
        ("imageMode", "Sometimes", "Sometimes"),
        ("numImages", [1, 2], ""),
    ],
)
def test_a_bad_put_names_block_and_field_and_writes_nothing(ioc, field, value, why):
    pvs = {"exposure": "Exposure", "imageMode": "ImageMode", "numImages": "NumImages"}

    async def scenario():
        async with started("DRV") as process:
            block = process.get_block("DRV")
            before = block[field].value
            with pytest.raises(BadValueError) as info:
                await process.put(["DRV", field], value)
            message = str(info.value)
            assert "DRV" in message and field in message, message
            assert why in message
            assert block[field].value == before
            raw = epics.caget(f"{PREFIX}:CAM:{pvs[field]}", use_monitor=False)
            return before, raw

    before, raw = run(scenario())
    if isinstance(before, str):
        assert raw == ("Single", "Multiple", "Continuous").index(before)
    else:
        assert raw == before


def test_a_motor_stop_action_stops_a_move(ioc):
    async def scenario():
        async with started("M2") as process:
            m2 = process.get_block("M2")
            # from 0, wherever an earlier test left the session IOC's M2 (the
            # trajectory test of test_ca_devices leaves it at -4)
            await process.put(["M2", "velocity"], 1000.0)
            await process.put(["M2", "position"], 0.0)
            await process.put(["M2", "velocity"], 5.0)
            moving = spawn(process.put(["M2", "position"], 50.0))
            await until(lambda: m2.doneMoving.value is False, what="moving")
            await process.post(["M2", "stop"])  # returns once DMOV reads 1
            # the action's wait on DMOV is satisfied only once every channel
            # of DMOV on this loop (the block's doneMoving too) was given it
            assert m2.doneMoving.value is True
            await moving  # the move's put completes once stopped
            assert 0.0 < m2.position.value < 50.0
            await process.put(["M2", "velocity"], 1000.0)
            await process.put(["M2", "position"], 0.0)

    run(scenario())


def test_what_the_pv_cannot_take_is_refused_before_writing(ioc):
    async def scenario():
        async with started("HDF", "TRAJ") as process:
            hdf, traj = process.get_block("HDF"), process.get_block("TRAJ")
            await process.put(["HDF", "fileName"], "keep")
            with pytest.raises(Exception) as info:  # a 1024-byte waveform
                await process.put(["HDF", "fileName"], "x" * 2000)
            assert "does not fit" in str(info.value), info.value
            assert "HDF.fileName" in str(info.value), info.value
            assert hdf.fileName.value == "keep"
            raw = epics.caget(f"{PREFIX}:HDF:FileName_RBV", as_string=True)
            assert raw == "keep"
            before = traj.positionsA.value
            with pytest.raises(Exception, match="50001 values do not fit in 50000"):
                await process.put(["TRAJ", "positionsA"], np.zeros(50_001))
            assert traj.positionsA.value == before

    run(scenario())


def test_an_alarm_of_the_pv_reaches_the_attribute(ioc):
    async def scenario():
        async with started("POS") as process:
            pos = process.get_block("POS")
            await process.put(["POS", "delete"], True)
            await process.put(["POS", "xml"], "<pos_layout><positions>")  # broken
            await until(
                lambda: pos.positions.alarm.severity is AlarmSeverity.MAJOR_ALARM,
                what="MAJOR alarm on Qty",
            )
            assert pos.positions.alarm.message == "STATE"
            good = '<pos_layout><positions><position x="1"/></positions></pos_layout>'
            await process.put(["POS", "xml"], good)
            await until(lambda: pos.positions.alarm.severity == 0, what="cleared")
            assert pos.positions.value == 1
            await process.put(["POS", "delete"], True)

    run(scenario())

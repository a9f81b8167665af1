"""The design document's detector manager example, verbatim, on the IOC.

``tests/unit/config_fixtures/blocks/demo/DetectorManager.yaml`` is the
document's text: ``block.ADCore.PositionPlugin`` (packaged, on CA) fed by
PosPluginPart, ``client.ADCore.DetectorDriver`` attached as ``sim:drv``.
"""

from __future__ import annotations

import asyncio
from pathlib import Path

from malcolm.config.build import build_definition
from malcolm.core import Process

from .conftest import PREFIX, run, spawn, until

FIXTURES = Path(__file__).parents[2] / "unit" / "config_fixtures" / "blocks"


def line(size: int) -> dict:
    return {
        "typeid": "scanpointgenerator:generator/CompoundGenerator:1.0",
        "generators": [
            {
                "typeid": "scanpointgenerator:generator/LineGenerator:1.0",
                "axes": ["x"],
                "units": ["mm"],
                "start": [0],
                "stop": [1],
                "size": size,
                "alternate": False,
            }
        ],
        "excluders": [],
        "mutators": [],
        "duration": 0.002,
    }


def test_the_document_manager_scans_with_the_ca_position_plugin(ioc):
    process = Process("ca-test", channels={"ca": "pyepics"})
    values = {"prefix": f"{PREFIX}:CAM"}
    build_definition("ADCore.DetectorDriver", values, "sim:drv", process=process)
    build_definition(
        "demo.DetectorManager", {"pvprefix": PREFIX}, "DET", [FIXTURES], process
    )
    assert process.mris == ["sim:drv", "DET:pos", "DET"]

    async def scenario():
        await process.start()
        try:
            pos, drv = process.get_block("DET:pos"), process.get_block("sim:drv")
            assert pos.health.value == "OK" and drv.health.value == "OK"
            await process.post(["DET", "configure"], {"generator": line(150)})
            # Configure's puts went to the IOC; the plugin parsed 100 positions
            assert pos.enableCallbacks.value is True
            assert pos.idStart.value == 1
            await until(lambda: pos.positions.value == 100, what="100 loaded")
            # frames come from the driver: as many as the scan has points
            await process.put(["sim:drv", "exposure"], 0.002)
            await process.put(["sim:drv", "acquirePeriod"], 0.002)
            await process.put(["sim:drv", "numImages"], 150)
            await process.put(["sim:drv", "imageMode"], "Multiple")
            scan = spawn(process.post(["DET", "run"]))
            await until(lambda: pos.running.value, what="plugin running")
            acquiring = spawn(process.put(["sim:drv", "acquire"], "Acquire"))
            await asyncio.wait_for(scan, 30)
            assert process.get_block("DET").state.value == "Finished"
            assert pos.processed.value == 150  # every position tagged a frame
            assert pos.positions.value == 0 and pos.running.value is False
            await asyncio.wait_for(acquiring, 10)  # the driver's put is done
            assert drv.numImagesCounter.value == 150
            await process.put(["sim:drv", "imageMode"], "Single")
            await process.put(["sim:drv", "acquirePeriod"], 0.1)
        finally:
            await process.stop()

    run(scenario(), timeout=90)

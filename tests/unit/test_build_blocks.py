"""Building the design document's block examples, and the soft parts."""

import asyncio
from pathlib import Path

import pytest

from malcolm.config.build import build_block, build_definition
from malcolm.config.builtin import AreaDetectorController, GenericScanController
from malcolm.config.definitions import (
    available_definitions,
    expand,
    find_definition,
    load_definition,
)
from malcolm.controllers.stateful import StatefulController
from malcolm.core import (
    AbortedError,
    ChoiceMeta,
    NotWriteableError,
    NumberMeta,
    Process,
    StringMeta,
)
from malcolm.parts.adcore import (
    DetectorPart,
    DriverRunPart,
    MotorPart,
    PosPluginPart,
    ZebraPart,
)
from malcolm.parts.base import ChildPart
from malcolm.parts.soft import CADoublePart, CAEnumPart, GroupPart
from malcolm.sim.position_plugin import PositionPlugin

FIXTURES = Path(__file__).parent / "config_fixtures"
SEARCH = [FIXTURES / "blocks"]


def run(coro):
    return asyncio.run(asyncio.wait_for(coro, 30))


def test_detector_driver_attributes():
    process = build_definition("ADCore.DetectorDriver", {"prefix": "BL"}, "DRV", SEARCH)
    assert process.mris == ["DRV"]
    controller = process.get_controller("DRV")
    assert type(controller) is StatefulController  # the default controller
    block = controller.block
    fields = [n for n in block if n not in ("health", "state", "reset", "disable")]
    # the design document's fields first, then the packaged driver's extras
    assert fields[:4] == ["configuration", "exposure", "xml", "acquire"]
    assert "numImages" in fields and "imageMode" in fields

    group = block.configuration.meta
    assert isinstance(group, ChoiceMeta)
    assert group.choices == ("expanded", "collapsed")
    assert group.tags == ("widget:group",)
    assert group.label == "Configuration Parameters"
    assert group.description == "These will be used to configure the device"

    exposure = block.exposure.meta
    assert isinstance(exposure, NumberMeta) and exposure.dtype == "float64"
    assert exposure.description == "Exposure time for each frame"
    assert exposure.tags == ("widget:textinput", "group:configuration")
    assert exposure.writeable is True  # the packaged driver can set it

    xml = block.xml.meta
    assert isinstance(xml, StringMeta)
    assert xml.tags == ("widget:textarea", "group:configuration")
    assert xml.writeable is True

    acquire = block.acquire.meta
    assert isinstance(acquire, ChoiceMeta) and acquire.choices == ("0", "1")
    assert acquire.tags == ("widget:toggle",) and acquire.writeable is True

    # the PV names are kept for the Channel Access adapter
    parts = controller.parts
    assert isinstance(parts["exposure"], CADoublePart)
    assert (parts["exposure"].pv, parts["exposure"].rbv) == (
        "BL:Exposure",
        "BL:Exposure_RBV",
    )
    assert (parts["xml"].pv, parts["xml"].rbv) == ("BL:Filename", "BL:Filename")
    assert isinstance(parts["configuration"], GroupPart)


def test_soft_channels_take_puts_of_writeable_attributes():
    process = build_definition("ADCore.DetectorDriver", {"prefix": "BL"}, "DRV", SEARCH)

    async def scenario():
        await process.start()
        await process.put(["DRV", "xml"], "<xml/>")
        await process.put(["DRV", "acquire"], 1)
        with pytest.raises(NotWriteableError):
            await process.put(["DRV", "numImagesCounter"], 3)
        await process.put(["DRV", "configuration"], "collapsed")
        await process.stop()

    run(scenario())
    block = process.get_block("DRV")
    assert block.xml.value == "<xml/>"
    assert block.acquire.value == "1"
    assert block.configuration.value == "collapsed"
    parts = process.get_controller("DRV").parts
    records = process.backends["ca"].records  # the soft backend's PVs
    assert parts["xml"].channel.write == "BL:Filename"
    assert records["BL:Filename"].value == "<xml/>"
    assert records["BL:Filename"].puts == 1
    # read-only: no put channel
    assert parts["numImagesCounter"].channel.write is None
    assert records["BL:NumImagesCounter_RBV"].puts == 0


def test_manager_example_makes_its_child_and_attaches_its_client():
    process = build_definition(
        "demo.DetectorManager", {"pvprefix": "BL18I-DET"}, "BL18I:DET", SEARCH
    )
    # the child first, then the client's stand-in, then the manager
    assert process.mris == ["BL18I:DET:pos", "sim:drv", "BL18I:DET"]
    manager = process.get_controller("BL18I:DET")
    assert isinstance(manager, AreaDetectorController)
    assert manager.model.name == "AreaDetectorRunnableDevice"
    assert manager.initial_design == "simDetectorDefaultSetup"

    pos = manager.parts["pos"]
    assert type(pos) is PosPluginPart and pos.controls is PositionPlugin
    assert pos.mri == "BL18I:DET:pos"
    drv = manager.parts["drv"]
    assert type(drv) is DriverRunPart
    assert (drv.mri, drv.readonly) == ("sim:drv", False)
    assert list(manager.parts) == ["pos", "drv"]

    child = process.get_block("BL18I:DET:pos")
    assert child.xml.meta.writeable and child.positions.value == 0
    assert process.get_controller("BL18I:DET:pos").parts["xml"].pv == (
        "BL18I-DET:POS:Filename"
    )

    standin = process.get_block("sim:drv")
    assert "standin" in standin.meta.tags
    assert "Soft stand-in for ADCore.DetectorDriver" in standin.meta.description
    assert process.get_controller("sim:drv").parts["exposure"].pv == "sim:drv:Exposure"


def test_a_client_of_an_existing_block_makes_no_stand_in():
    process = build_definition(
        "ADCore.DetectorDriver", {"prefix": "S"}, "sim:drv", SEARCH
    )
    build_definition(
        "demo.DetectorManager", {"pvprefix": "P"}, "DET", SEARCH, process=process
    )
    assert process.mris == ["sim:drv", "DET:pos", "DET"]
    assert "standin" not in process.get_block("sim:drv").meta.tags


def test_coordination_example_builds_a_generic_scan_block():
    values = {"det": "BL18I:DET", "zebra": "BL18I:Z1", "motor": "BL18I:MOT"}
    process = build_definition("demo.GenericScan", values, "BL18I:SCAN", SEARCH)
    assert process.mris == ["BL18I:SCAN"]
    scan = process.get_controller("BL18I:SCAN")
    assert isinstance(scan, GenericScanController)
    assert "configure" in scan.block and "run" in scan.block
    parts = list(scan.parts.values())
    assert [type(p) for p in parts] == [DetectorPart, ZebraPart, MotorPart]
    assert [p.name for p in parts] == ["DetectorPart", "ZebraPart", "MotorPart"]
    assert [p.mri for p in parts] == ["BL18I:DET", "BL18I:Z1", "BL18I:MOT"]
    assert parts[0].input == "BL18I:DET"


def test_child_block_without_part_gets_a_plain_child_part(tmp_path):
    (tmp_path / "top").mkdir()
    (tmp_path / "top" / "Box.yaml").write_text(
        "block.demo.Counter:\n    name: c\n\nca.Enum:\n    name: mode\n"
        "    pv: X:Mode\n    choices: [Idle, Busy]\n"
    )
    process = build_definition("top.Box", {}, "BOX", [tmp_path])
    assert process.mris == ["BOX:c", "BOX"]
    controller = process.get_controller("BOX")
    assert type(controller.parts["c"]) is ChildPart
    assert controller.parts["c"].mri == "BOX:c"
    mode = controller.parts["mode"]
    assert isinstance(mode, CAEnumPart)
    assert process.get_block("BOX").mode.meta.choices == ("Idle", "Busy")
    assert process.get_block("BOX").mode.meta.writeable is False


def test_build_block_adds_to_an_existing_process():
    definition = load_definition(find_definition("demo.Counter"), name="demo.Counter")
    process = Process()
    controller = build_block(process, expand(definition, {}, mri="C1"))
    assert process.get_controller("C1") is controller
    assert "increment" in controller.block


def test_pos_plugin_part_runs_a_scan_on_the_simulated_manager():
    process = build_definition("ADCore.SimDetectorManager", {}, "SIM:DET")
    assert process.mris == ["SIM:DET:pos", "SIM:DRV", "SIM:DET"]
    generator = {
        "typeid": "scanpointgenerator:generator/CompoundGenerator:1.0",
        "generators": [
            {
                "typeid": "scanpointgenerator:generator/LineGenerator:1.0",
                "axes": ["x"],
                "units": ["mm"],
                "start": [0],
                "stop": [1],
                "size": 250,
                "alternate": False,
            }
        ],
        "excluders": [],
        "mutators": [],
        "duration": 0.001,
    }

    async def scenario():
        await process.start()
        await process.post(["SIM:DET", "configure"], {"generator": generator})
        pos = process.get_block("SIM:DET:pos")
        assert pos.positions.value == 100 and pos.enableCallbacks.value is True
        await process.post(["SIM:DET", "run"])
        det = process.get_block("SIM:DET")
        assert det.state.value == "Finished"
        assert pos.processed.value == 250
        assert pos.running.value is False
        assert process.get_controller("SIM:DET:pos").parts["plugin"].xml_puts == 3
        await process.stop()

    run(scenario())


PACKAGE_VALUES = {
    "ADCore.NDPosPlugin": {"prefix": "BL"},
    "ADCore.SimDetector": {"prefix": "BL"},
    "ADCore.DetectorDriver": {"prefix": "BL"},
    "ADCore.PositionPlugin": {"prefix": "BL"},
    "ADCore.HDFWriter": {"prefix": "BL"},
    "ADCore.DetectorManager": {"prefix": "BL"},
    "motor.MotorRecord": {"prefix": "BL:M1"},
    "pmac.TrajectoryScan": {"prefix": "BL"},
    "pmac.MotorControllerManager": {"prefix": "BL"},
    "demo.Scan": {"det1": "D1", "det2": "D2", "x": "X", "y": "Y"},
}


@pytest.mark.parametrize(
    "name",
    [
        n
        for n in available_definitions()
        # demo/process.yaml is the demo's process file, not a definition
        if n.split(".")[0] in ("ADCore", "demo", "motor", "pmac")
        and n != "demo.process"
    ],
)
def test_every_package_definition_builds(name):
    process = build_definition(name, PACKAGE_VALUES.get(name, {}), "TOP")
    assert "TOP" in process.mris


def test_nd_pos_plugin_has_the_fields_pos_plugin_part_uses():
    process = build_definition("ADCore.NDPosPlugin", {"prefix": "BL"}, "POS")
    block = process.get_block("POS")
    assert set(PositionPlugin.fields) <= set(block)
    sim = build_definition("ADCore.SimPositionPlugin", {}, "SIM").get_block("SIM")
    assert set(PositionPlugin.fields) <= set(sim)
    parts = process.get_controller("POS").parts
    assert (parts["idStart"].pv, parts["idStart"].rbv) == (
        "BL:POS:IDStart",
        "BL:POS:IDStart_RBV",
    )
    assert (parts["positions"].pv, parts["positions"].rbv) == (None, "BL:POS:Qty")
    assert not block.positions.meta.writeable and block.start.meta.writeable


def test_abort_stops_the_simulated_position_plugin():
    process = build_definition("ADCore.SimDetectorManager", {}, "SIM:DET")
    generator = {
        "typeid": "scanpointgenerator:generator/CompoundGenerator:1.0",
        "generators": [
            {
                "typeid": "scanpointgenerator:generator/LineGenerator:1.0",
                "axes": ["x"],
                "units": ["mm"],
                "start": [0],
                "stop": [1],
                "size": 100000,
                "alternate": False,
            }
        ],
        "excluders": [],
        "mutators": [],
        "duration": 0.001,
    }

    async def scenario():
        await process.start()
        await process.post(["SIM:DET", "configure"], {"generator": generator})
        running = asyncio.ensure_future(process.post(["SIM:DET", "run"]))
        pos = process.get_block("SIM:DET:pos")
        while pos.processed.value < 20:
            await asyncio.sleep(0.005)
        await process.post(["SIM:DET", "abort"])
        with pytest.raises(AbortedError):
            await running
        assert process.get_block("SIM:DET").state.value == "Aborted"
        assert pos.running.value is False
        stopped_at = pos.processed.value
        await asyncio.sleep(0.05)
        assert pos.processed.value == stopped_at
        assert not process._subs.get("SIM:DET:pos")
        await process.stop()

    run(scenario())

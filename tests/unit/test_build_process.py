"""Building processes from process files, the demo among them."""

import asyncio
import io
from pathlib import Path

import pytest

from malcolm.config.build import build_process
from malcolm.config.builtin import AreaDetectorController, GenericScanController
from malcolm.config.errors import ConfigError
from malcolm.controllers.runnable import RunnableController
from malcolm.controllers.stateful import StatefulController
from malcolm.demo import DEMO_PROCESS_FILE, demo_generator, demo_process, run_demo_scan
from malcolm.parts.demo import (
    CounterPart,
    HelloPart,
    MotorMovePart,
    RunnableChildPart,
    SimDetectorPart,
    SimMotorPart,
)

FIXTURES = Path(__file__).parent / "config_fixtures"
SEARCH = [FIXTURES / "blocks"]
DEMO_MRIS = ["HELLO", "COUNTER", "MOTOR:X", "MOTOR:Y", "DET1", "DET2", "SCAN"]


def test_demo_process_is_built_from_yaml():
    process = demo_process()
    assert process.name == "demo"
    assert process.mris == DEMO_MRIS
    kinds = {
        mri: (type(c).__name__, [type(p) for p in c.parts.values()])
        for mri in process.mris
        for c in [process.get_controller(mri)]
    }
    assert kinds == {
        "HELLO": ("StatefulController", [HelloPart]),
        "COUNTER": ("StatefulController", [CounterPart]),
        "MOTOR:X": ("StatefulController", [SimMotorPart]),
        "MOTOR:Y": ("StatefulController", [SimMotorPart]),
        "DET1": ("RunnableController", [SimDetectorPart]),
        "DET2": ("RunnableController", [SimDetectorPart]),
        "SCAN": (
            "RunnableController",
            [RunnableChildPart, RunnableChildPart, MotorMovePart, MotorMovePart],
        ),
    }
    assert process.get_block("MOTOR:Y").meta.description == "Motor Y"
    assert process.get_block("HELLO").meta.description == "Says hello"
    scan = process.get_controller("SCAN")
    assert [(p.name, p.mri) for p in scan.parts.values()] == [
        ("DET1", "DET1"),
        ("DET2", "DET2"),
        ("x", "MOTOR:X"),
        ("y", "MOTOR:Y"),
    ]
    assert scan.parts["y"].axis == "y"
    assert process.get_controller("MOTOR:X").parts["motor"].initial_velocity == 100.0


def test_demo_prefix_is_a_define():
    process = demo_process("BL01:")
    assert process.mris == [f"BL01:{m}" for m in DEMO_MRIS]
    assert process.get_controller("BL01:SCAN").parts["x"].mri == "BL01:MOTOR:X"


def test_demo_process_from_yaml_scans():
    process = demo_process("T:")
    out = io.StringIO()

    async def scenario():
        await process.start()
        try:
            await run_demo_scan(process, demo_generator(2, 3, 0.001), out=out)
        finally:
            await process.stop()

    asyncio.run(asyncio.wait_for(scenario(), 30))
    assert out.getvalue().rstrip().endswith("T:SCAN Finished")
    assert process.get_block("T:DET1").framesTaken.value == 6
    assert process.get_block("T:MOTOR:X").position.value in (0.0, 1.0)


def test_users_can_copy_the_demo_process_file(tmp_path):
    copy = tmp_path / "process.yaml"
    copy.write_text(DEMO_PROCESS_FILE.read_text().replace('value: ""', "value: LAB-"))
    process = build_process(copy)
    assert process.name == "process"
    assert process.mris == [f"LAB-{m}" for m in DEMO_MRIS]


def test_beamline_process_file():
    process = build_process(FIXTURES / "process" / "beamline.yaml", SEARCH)
    assert process.mris == ["BL18I:DRV", "BL18I:DET:pos", "sim:drv", "BL18I:DET",
                            "BL18I:SCAN"]  # fmt: skip
    assert isinstance(process.get_controller("BL18I:DET"), AreaDetectorController)
    assert isinstance(process.get_controller("BL18I:SCAN"), GenericScanController)
    assert isinstance(process.get_controller("BL18I:SCAN"), RunnableController)
    assert isinstance(process.get_controller("BL18I:DRV"), StatefulController)
    drv = process.get_controller("BL18I:DRV").parts["exposure"]
    assert drv.pv == "BL18I-EA-DET-01:Exposure"


def test_a_client_of_a_block_later_in_the_process_makes_no_stand_in(tmp_path):
    path = tmp_path / "p.yaml"
    path.write_text(
        "block.demo.DetectorManager:\n    mri: DET\n    pvprefix: P\n"
        "block.ADCore.DetectorDriver:\n    mri: sim:drv\n    prefix: S\n"
    )
    process = build_process(path, SEARCH)
    assert process.mris == ["DET:pos", "DET", "sim:drv"]
    assert "standin" not in process.get_block("sim:drv").meta.tags


def test_override_of_an_undefined_name_is_an_error():
    with pytest.raises(ConfigError) as info:
        build_process(DEMO_PROCESS_FILE, defines={"prefx": "X"})
    assert str(info.value) == f"{DEMO_PROCESS_FILE}:1: no define 'prefx' to override"
    with pytest.raises(ConfigError, match=r"process.yaml:7: value of 'prefix' must be"):
        build_process(DEMO_PROCESS_FILE, defines={"prefix": 5})

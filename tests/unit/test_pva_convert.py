"""malcolm.io.pva.convert: Malcolm structures <-> p4p Values (interop.md §2)."""

import asyncio

import pytest

from malcolm.demo import demo_generator, demo_process
from malcolm.io.pva.convert import to_dict, to_value


@pytest.fixture(scope="module")
def blocks():
    async def main():
        process = demo_process()
        await process.start()
        try:
            await process.post(
                ["SCAN", "configure"],
                {"generator": demo_generator(), "axesToMove": ["x"]},
            )
            await process.post(["HELLO", "greet"], {"name": "me"})
            return {mri: process.get([mri]) for mri in process.mris}
        finally:
            await process.stop()

    return asyncio.run(main())


def test_every_demo_block_round_trips(blocks):
    for mri, data in blocks.items():
        assert to_dict(to_value(data)) == data, mri


def test_typeids_and_types(blocks):
    scan = to_value(blocks["SCAN"])
    assert scan.getID() == "malcolm:core/Block:1.0"
    assert list(scan.keys())[:3] == ["meta", "health", "state"]
    assert scan["meta"].getID() == "malcolm:core/BlockMeta:1.0"
    types = dict(scan.type().aspy()[2])
    # values typed by their metas: int32 stays int32_t, choices are strings
    assert dict(types["completedSteps"][2])["value"] == "i"
    assert dict(types["state"][2])["value"] == "s"
    assert dict(types["simultaneousAxes"][2])["value"] == "as"
    layout = scan["layout"]
    assert layout.getID() == "epics:nt/NTTable:1.0"
    assert list(layout["labels"]) == ["Name", "Fullname", "X", "Y", "Visible"]
    configure = scan["configure"]
    assert configure.getID() == "malcolm:core/Method:1.1"
    assert configure["took"].getID() == "malcolm:core/MethodLog:1.0"
    assert configure["meta"].getID() == "malcolm:core/MethodMeta:1.1"
    assert configure["meta.takes"].getID() == "malcolm:core/MapMeta:1.0"
    assert configure["took.value.generator"].getID() == (
        "scanpointgenerator:generator/CompoundGenerator:1.0"
    )
    assert scan["health.alarm"].getID() == "alarm_t"
    assert scan["health.timeStamp"].getID() == "time_t"


def test_generator_as_gda_sends_it():
    gen = demo_generator()
    value = to_value(gen)
    assert value.getID() == "scanpointgenerator:generator/CompoundGenerator:1.0"
    line = value["generators"][0]
    assert line.getID() == "scanpointgenerator:generator/LineGenerator:1.0"
    assert dict(line.type().aspy()[2]) == {
        "axes": "as",
        "units": "as",
        "start": "ad",
        "stop": "ad",
        "size": "l",
        "alternate": "?",
    }
    assert value["excluders"] == [] and value.type()["excluders"] == "av"
    assert to_dict(value) == gen

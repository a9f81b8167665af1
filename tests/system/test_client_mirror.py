"""A mirror (RemoteBlock) of each block of the served demo is the served
structure field for field (metas, typeids, methods' takes and defaults);
a table put, and validate's returned structure, go through it; its
methods' took and returned follow the server's."""

from __future__ import annotations

import asyncio

from malcolm.core import Process
from malcolm.io.pva.client import RemoteBlock
from malcolm.io.pva.convert import to_dict

from .test_client_cli import free_port, serve_demo, stop

MRIS = ["HELLO", "COUNTER", "MOTOR:X", "DET1", "SCAN"]

GENERATOR = {
    "typeid": "scanpointgenerator:generator/CompoundGenerator:1.0",
    "generators": [
        {
            "typeid": "scanpointgenerator:generator/LineGenerator:1.0",
            "axes": ["x"],
            "units": ["mm"],
            "start": [0.0],
            "stop": [1.0],
            "size": 3,
            "alternate": False,
        }
    ],
    "excluders": [],
    "mutators": [],
    "duration": 0.01,
}


def test_mirrors_are_the_served_blocks():
    port = free_port()
    a = serve_demo(port)
    context = a.context()

    async def main():
        process = Process("b")
        for mri in MRIS:
            process.add_controller(RemoteBlock(mri, f"127.0.0.1:{port}"))
        await process.start()
        try:
            for mri in MRIS:
                served = to_dict(context.get(mri))
                assert process.get([mri]) == served, mri
            scan = process.get_block("SCAN")
            # a table put: rows of the layout moved
            layout = dict(scan.layout.value)
            moved = {**layout, "x": tuple(1.5 for _ in layout["x"])}
            await process.put(["SCAN", "layout"], moved)
            served = to_dict(context.get("SCAN.layout"))
            assert served["value"]["x"] == [1.5] * len(layout["x"])
            assert scan.layout.value["x"] == (1.5,) * len(layout["x"])
            # validate returns the structure it was given (a generator too)
            returned = await process.post(
                ["SCAN", "validate"], {"generator": GENERATOR, "axesToMove": ["x"]}
            )
            assert returned["generator"]["typeid"] == GENERATOR["typeid"]
            assert returned["generator"]["generators"][0]["size"] == 3
            assert returned["axesToMove"] == ["x"]
            assert scan.validate.took.present == [
                "generator",
                "axesToMove",
                "breakpoints",
            ]
            assert scan.validate.returned.value["axesToMove"] == ["x"]
            assert process.get(["SCAN", "validate"]) == to_dict(
                context.get("SCAN.validate")
            )
        finally:
            await process.stop()

    try:
        asyncio.run(main())
    finally:
        stop(a)

"""An operation goes on when its caller stops waiting (the caller's task
cancelled): its outcome is the block's state; an error it ends with after
that is nobody's to read and is not reported as lost."""

from __future__ import annotations

import asyncio
from typing import Any

from malcolm.controllers.runnable import RunnableController
from malcolm.core import Process
from malcolm.fsm import RunnableDevice
from malcolm.parts import Part

from .scans import compound, run


class GatedPart(Part):
    """Its Configure waits for ``gate``; raises if ``fail`` is set."""

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.gate = asyncio.Event()
        self.fail = False

    @RunnableDevice.Configure
    async def configure(self, task: Any, device: Any) -> None:
        await self.gate.wait()
        if self.fail:
            raise RuntimeError("the hardware said no")


async def make() -> tuple[Process, GatedPart]:
    process = Process()
    part = GatedPart("gated")
    process.add_controller(RunnableController("OP", [part]))
    await process.start()
    return process, part


def test_the_operation_goes_on_when_its_caller_is_cancelled():
    async def scenario():
        p, part = await make()
        caller = asyncio.ensure_future(
            p.post(["OP", "configure"], {"generator": compound(("x", 3))})
        )
        while p.get(["OP", "state", "value"]) != "Configuring":
            await asyncio.sleep(0.001)
        caller.cancel()
        await asyncio.wait({caller})
        assert caller.cancelled()
        assert p.get(["OP", "state", "value"]) == "Configuring"
        part.gate.set()
        while p.get(["OP", "state", "value"]) == "Configuring":
            await asyncio.sleep(0.001)
        assert p.get(["OP", "state", "value"]) == "Armed"
        assert p.get(["OP", "totalSteps", "value"]) == 3

    run(scenario)


def test_an_error_after_the_caller_left_ends_in_fault():
    async def scenario():
        p, part = await make()
        part.fail = True
        caller = asyncio.ensure_future(
            p.post(["OP", "configure"], {"generator": compound(("x", 3))})
        )
        while p.get(["OP", "state", "value"]) != "Configuring":
            await asyncio.sleep(0.001)
        caller.cancel()
        await asyncio.wait({caller})
        part.gate.set()
        while p.get(["OP", "state", "value"]) == "Configuring":
            await asyncio.sleep(0.001)
        assert p.get(["OP", "state", "value"]) == "Fault"
        assert "the hardware said no" in p.get(["OP", "health", "value"])

    run(scenario)

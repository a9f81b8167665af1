"""A manager's runnable children (``RunnableChildPart``), on live blocks.

- After any way out of a scan that is not ``abort`` (a fault while running
  or paused, a disable while running or paused, a child aborted by someone
  else), the manager's reset brings each child back to where its next call
  is allowed: a new scan configures and runs to the end (review A, F1).
- The manager's Validate asks the child's ``validate()``: a child's refusal
  refuses the manager's configure and validate with nothing changed, and a
  child's tweak is the manager's (review A, F5).
"""

from __future__ import annotations

import asyncio
from typing import Any

import pytest

from malcolm.controllers.runnable import RunnableController
from malcolm.core import BadValueError, MalcolmError, Process
from malcolm.demo import demo_generator, demo_process
from malcolm.fsm import RunnableDevice
from malcolm.parts import Part
from malcolm.parts.demo import RunnableChildPart, SimDetectorPart

from .scans import compound, run, steps

DETS = ("DET1", "DET2")


async def wait_for(predicate, timeout: float = 10.0) -> None:
    async with asyncio.timeout(timeout):
        while not predicate():
            await asyncio.sleep(0.002)


def states(process: Process, *mris: str) -> dict[str, str]:
    return {mri: process.get([mri, "state", "value"]) for mri in mris}


# ---- F1: every way out of a scan leaves children a new scan can use


async def fault_by_an_outside_put(process: Process) -> None:
    """A put on a Fixed row of the saved design: SCAN goes to Fault."""
    await process.put(["MOTOR:X", "velocity"], 3.0)


async def pause_then(process: Process, then: Any) -> None:
    await process.post(["SCAN", "pause"])
    assert states(process, "SCAN", *DETS) == dict.fromkeys(("SCAN", *DETS), "Paused")
    await then(process)


async def disable(process: Process) -> None:
    await process.post(["SCAN", "disable"])


async def abort_a_child_from_outside(process: Process) -> None:
    await process.post(["DET1", "abort"])


WAYS_OUT = {
    "fault while running": (fault_by_an_outside_put, "Fault"),
    "fault while paused": (
        lambda p: pause_then(p, fault_by_an_outside_put),
        "Fault",
    ),
    "disable while running": (disable, "Disabled"),
    "disable while paused": (lambda p: pause_then(p, disable), "Disabled"),
    "a child aborted from outside": (abort_a_child_from_outside, "Fault"),
}


@pytest.mark.parametrize("way_out", list(WAYS_OUT))
def test_after_any_way_out_of_a_scan_reset_brings_the_children_back(way_out):
    leave, lands = WAYS_OUT[way_out]

    async def scenario():
        process = demo_process()
        await process.start()
        scan = process.get_block("SCAN")
        await process.post(["SCAN", "save"], {"design": "fixed"})
        generator = demo_generator(5, 8, 0.02)
        await process.post(["SCAN", "configure"], {"generator": generator})
        pending = asyncio.ensure_future(process.post(["SCAN", "run"]))
        await wait_for(lambda: scan.completedSteps.value >= 2)
        await leave(process)
        with pytest.raises(MalcolmError):
            await pending
        assert scan.state.value == lands
        await process.post(["SCAN", "reset"])
        # the children are where their next call is allowed, now
        assert states(process, "SCAN", *DETS) == dict.fromkeys(("SCAN", *DETS), "Ready")
        for det in DETS:
            assert process.get([det, "configure", "meta", "writeable"])
        # and a new scan runs to the end
        await process.post(
            ["SCAN", "configure"], {"generator": demo_generator(2, 3, 0.001)}
        )
        await process.post(["SCAN", "run"])
        assert (scan.state.value, scan.health.value) == ("Finished", "OK")
        for det in DETS:
            block = process.get_block(det)
            assert (block.state.value, block.framesTaken.value) == ("Finished", 6)
        await process.stop()

    run(scenario)


def test_a_disabled_manager_disables_its_children_and_its_reset_resets_them():
    """As the reference's ChildPart does on disable (Ready children too)."""

    async def scenario():
        process = demo_process()
        await process.start()
        await process.post(["SCAN", "disable"])
        assert states(process, "SCAN", *DETS) == dict.fromkeys(
            ("SCAN", *DETS), "Disabled"
        )
        await process.post(["SCAN", "reset"])
        assert states(process, "SCAN", *DETS) == dict.fromkeys(("SCAN", *DETS), "Ready")
        await process.stop()

    run(scenario)


def test_reset_of_a_finished_manager_resets_its_children_without_aborting():
    """A child that may be reset is reset, not aborted first."""

    async def scenario():
        process = demo_process()
        await process.start()
        seen: list[str] = []
        process.subscribe(
            ["DET1", "state", "value"], lambda v: seen.append(v), delta=False
        )
        await process.post(
            ["SCAN", "configure"], {"generator": demo_generator(1, 2, 0.001)}
        )
        await process.post(["SCAN", "run"])
        del seen[:]
        await process.post(["SCAN", "reset"])
        assert seen == ["Resetting", "Ready"]
        await process.stop()

    run(scenario)


# ---- F5: the manager's Validate asks its child


class MinExposure(Part):
    """Refuses, or (``tweak``) lengthens, a scan whose points are shorter
    than ``minimum`` seconds."""

    def __init__(self, name: str, minimum: float, tweak: bool = False) -> None:
        super().__init__(name)
        self.minimum = minimum
        self.tweak = tweak

    @RunnableDevice.Validate
    async def validate(self, task, device) -> dict[str, Any]:
        generator = device.params["generator"]
        duration = generator.get("duration", 0)
        if duration >= self.minimum:
            return {}
        if not self.tweak:
            raise BadValueError(
                f"duration {duration} is too short for this detector"
                f" (min {self.minimum} s)"
            )
        return {"generator": {**generator, "duration": self.minimum}}


def scan_of_one_detector(*det_parts: Part) -> tuple[Process, RunnableController]:
    process = Process()
    det = RunnableController(
        "DET", [SimDetectorPart("det", default_exposure=0.001), *det_parts]
    )
    process.add_controller(det)
    scan = RunnableController("SCAN", [RunnableChildPart("DET", "DET")])
    process.add_controller(scan)
    return process, scan


def test_a_configure_the_child_refuses_is_refused_by_the_manager():
    async def scenario():
        process, scan = scan_of_one_detector(MinExposure("min", 0.01))
        await process.start()
        short = compound(("x", 4), duration=0.001)
        with pytest.raises(MalcolmError, match="too short for this detector"):
            await process.post(["SCAN", "validate"], {"generator": short})
        with pytest.raises(MalcolmError, match="too short for this detector"):
            await process.post(["SCAN", "configure"], {"generator": short})
        assert (scan.block.state.value, scan.block.health.value) == ("Ready", "OK")
        assert states(process, "DET") == {"DET": "Ready"}
        assert steps(scan.block) == (0, 0, 0)
        # a scan the child accepts runs; then a refusal from Finished keeps it
        long = compound(("x", 2), duration=0.01)
        await process.post(["SCAN", "configure"], {"generator": long})
        await process.post(["SCAN", "run"])
        with pytest.raises(MalcolmError, match="too short for this detector"):
            await process.post(["SCAN", "configure"], {"generator": short})
        assert states(process, "SCAN", "DET") == {"SCAN": "Finished", "DET": "Finished"}
        assert steps(scan.block) == (2, 2, 2)
        assert scan.block.health.value == "OK"
        await process.stop()

    run(scenario)


def test_the_childs_tweaks_are_the_managers():
    async def scenario():
        process, scan = scan_of_one_detector(MinExposure("min", 0.01, tweak=True))
        await process.start()
        short = compound(("x", 3), duration=0.001)
        out = await process.post(["SCAN", "validate"], {"generator": short})
        assert out["generator"]["duration"] == 0.01
        assert out["generator"]["generators"] == short["generators"]
        await process.post(["SCAN", "configure"], {"generator": short})
        assert scan.device.params["generator"]["duration"] == 0.01
        assert process.get(["DET", "state", "value"]) == "Armed"
        await process.post(["SCAN", "run"])
        assert states(process, "SCAN", "DET") == {"SCAN": "Finished", "DET": "Finished"}
        await process.stop()

    run(scenario)


def test_a_child_that_cannot_validate_now_is_reset_and_configured():
    """A child left Aborted by someone else: the manager's Validate does not
    ask it (it may not validate there); Configure resets and configures it."""

    async def scenario():
        process, scan = scan_of_one_detector()
        await process.start()
        await process.post(["DET", "abort"])
        assert states(process, "DET") == {"DET": "Aborted"}
        await process.post(["SCAN", "configure"], {"generator": compound(("x", 2))})
        assert states(process, "SCAN", "DET") == {"SCAN": "Armed", "DET": "Armed"}
        await process.stop()

    run(scenario)

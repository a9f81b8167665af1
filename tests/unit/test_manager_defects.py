"""Manager defects (issue 7 items 7 and 8): a manager's own changes are not
drift; save is all or nothing; refused calls change nothing."""

from __future__ import annotations

import asyncio
import os
from pathlib import Path

import pytest

from malcolm.config.build import build_definition
from malcolm.controllers.runnable import RunnableController
from malcolm.controllers.stateful import StatefulController
from malcolm.core import BadValueError, MalcolmError, NotAllowedError, Process
from malcolm.demo import demo_generator, demo_process
from malcolm.fsm import RunnableDevice
from malcolm.parts import ChildPart, Part
from malcolm.parts.demo import CounterPart

from .scans import compound, run, steps


async def wait_for(predicate, timeout: float = 10.0) -> None:
    async with asyncio.timeout(timeout):
        while not predicate():
            await asyncio.sleep(0.002)


def designs() -> Path:
    return Path(os.environ["MALCOLM_DESIGNS_DIR"])


# ---- item 7: the acceptance lines, on the demo SCAN


def test_demo_scan_saved_then_configured_run_paused_resumed_finishes():
    async def scenario():
        process = demo_process()
        await process.start()
        scan = process.get_block("SCAN")
        await process.post(["SCAN", "save"], {"design": "demo"})
        assert (designs() / "SCAN" / "demo.yaml").is_file()
        generator = demo_generator(duration=0.02)
        await process.post(["SCAN", "configure"], {"generator": generator})
        pending = asyncio.ensure_future(process.post(["SCAN", "run"]))
        await wait_for(lambda: scan.completedSteps.value >= 4)
        await process.post(["SCAN", "pause"])
        await process.post(["SCAN", "resume"])
        await pending
        assert (scan.state.value, scan.health.value) == ("Finished", "OK")
        assert process.get_block("MOTOR:X").demand.value != 0.0  # the scan moved
        # reset writes the design's values back
        await process.post(["SCAN", "reset"])
        assert (scan.state.value, scan.health.value) == ("Ready", "OK")
        await wait_for(lambda: not process.get_block("MOTOR:X").moving.value)
        assert process.get_block("MOTOR:X").demand.value == 0.0
        await process.stop()

    run(scenario)


@pytest.mark.parametrize(
    ("field", "value"), [("velocity", 50.0), ("demand", 0.7)], ids=str
)
def test_a_put_from_outside_on_a_fixed_child_attribute_during_a_run_faults(
    field, value
):
    """velocity: only the outside client writes it; demand: the scan writes
    it too (its put may be in flight), but the latest put is the client's."""

    async def scenario():
        process = demo_process()
        await process.start()
        scan = process.get_block("SCAN")
        await process.post(["SCAN", "save"], {"design": "demo"})
        generator = demo_generator(duration=0.03)
        await process.post(["SCAN", "configure"], {"generator": generator})
        pending = asyncio.ensure_future(process.post(["SCAN", "run"]))
        await wait_for(lambda: scan.completedSteps.value >= 2)
        await process.put(["MOTOR:X", field], value)
        assert scan.state.value == "Fault"
        health = scan.health.value
        assert f"x.{field} is fixed at" in health and str(value) in health
        # the run's caller gets the fault's message, not "run was aborted"
        with pytest.raises(MalcolmError) as caught:
            await pending
        assert str(caught.value) == health
        await process.stop()

    run(scenario)


def test_the_design_documents_detector_manager_runs_after_a_save():
    process = build_definition("ADCore.SimDetectorManager", {}, "SIM:DET")

    async def scenario():
        await process.start()
        det = process.get_block("SIM:DET")
        await process.post(["SIM:DET", "save"], {"design": "saved"})
        await process.post(
            ["SIM:DET", "configure"], {"generator": compound(("x", 250))}
        )
        await process.post(["SIM:DET", "run"])
        assert (det.state.value, det.health.value) == ("Finished", "OK")
        assert process.get_block("SIM:DET:pos").processed.value == 250
        await process.stop()

    run(scenario)


# ---- item 7: what a Fixed row expects after the manager's own change


class SetsCounter(ChildPart):
    """Puts the child's counter at Configure, from async or threaded code."""

    def __init__(self, name: str, mri: str, threaded: bool) -> None:
        super().__init__(name, mri)
        self.threaded = threaded

    @RunnableDevice.Configure
    def configure_threaded(self, task, device):
        if self.threaded:
            task.put(self.child.counter, 5.0)

    @RunnableDevice.Configure
    async def configure(self, task, device):
        if not self.threaded:
            await task.put(self.child.counter, 5.0)


def manager_of_counter(threaded: bool) -> tuple[Process, RunnableController]:
    process = Process()
    process.add_controller(StatefulController("CHILD", [CounterPart("counter")]))
    manager = RunnableController(
        "MGR", [SetsCounter("C", "CHILD", threaded)], designs_dir=str(designs())
    )
    process.add_controller(manager)
    return process, manager


@pytest.mark.parametrize("threaded", [False, True], ids=["async", "threaded"])
def test_the_managers_own_change_moves_the_fixed_value_until_reset(threaded):
    async def scenario():
        process, manager = manager_of_counter(threaded)
        await process.start()
        await process.post(["MGR", "save"], {"design": "d"})
        await process.post(["MGR", "configure"], {"generator": compound(("x", 2))})
        assert (manager.current, manager.health.value) == ("Armed", "OK")
        assert process.get_block("CHILD").counter.value == 5.0
        # anyone else's change is drift, named against what the row expects
        await process.put(["CHILD", "counter"], 7.0)
        assert manager.current == "Fault"
        assert manager.health.value == (
            "MGR: C.counter is fixed at 5.0 (set by the manager; the design has"
            " 0.0), but it is 7.0"
        )
        # reset writes the design's value back
        await process.post(["MGR", "reset"])
        assert (manager.current, manager.health.value) == ("Ready", "OK")
        assert process.get_block("CHILD").counter.value == 0.0
        await process.stop()

    run(scenario)


# ---- item 8: save is all or nothing


class FailingSave(Part):
    @RunnableDevice.Save
    async def save(self, task, device):
        raise RuntimeError("cannot read the settings")


def test_a_failing_save_hook_writes_nothing_and_keeps_the_design():
    async def scenario():
        process = Process()
        manager = RunnableController(
            "MGR", [FailingSave("bad")], designs_dir=str(designs())
        )
        process.add_controller(manager)
        await process.start()
        with pytest.raises(MalcolmError, match="cannot read the settings"):
            await process.post(["MGR", "save"], {"design": "d"})
        assert not (designs() / "MGR" / "d.yaml").exists()
        assert manager.design.value == ""
        assert manager.current == "Fault"
        assert "cannot read the settings" in manager.health.value

    run(scenario)


@pytest.mark.parametrize(
    "name", ["x\n", "x" * 300, "\nx", "x\r"], ids=["newline", "300", "lead", "cr"]
)
def test_a_bad_design_name_is_refused_before_anything_changes(name):
    async def scenario():
        process = Process()
        manager = RunnableController("MGR", [], designs_dir=str(designs()))
        process.add_controller(manager)
        await process.start()
        with pytest.raises(BadValueError, match="design name"):
            await process.post(["MGR", "save"], {"design": name})
        assert (manager.current, manager.health.value) == ("Ready", "OK")
        assert manager.design.value == ""
        folder = designs() / "MGR"
        assert not folder.exists() or not any(folder.iterdir())

    run(scenario)


# ---- item 8: a refused configure, and validate() beside a configure


class Refuses(Part):
    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.entered = asyncio.Event()
        self.release = asyncio.Event()
        self.refuse = True

    @RunnableDevice.Validate
    async def validate(self, task, device):
        self.entered.set()
        await self.release.wait()
        if self.refuse:
            raise BadValueError("exposure too short for this detector")


def test_a_configure_a_part_refuses_changes_nothing():
    async def scenario():
        part = Refuses("det")
        part.release.set()
        process = Process()
        controller = RunnableController("DET", [part])
        process.add_controller(controller)
        await process.start()
        device = controller.device
        with pytest.raises(Exception, match="exposure too short"):
            await process.post(["DET", "configure"], {"generator": compound(("x", 4))})
        block = controller.block
        assert (block.state.value, block.health.value) == ("Ready", "OK")
        assert steps(block) == (0, 0, 0)
        assert controller.device is device
        # and from Finished: it stays Finished, with the scan it had
        part.refuse = False
        await process.post(["DET", "configure"], {"generator": compound(("x", 2))})
        await process.post(["DET", "run"])
        part.refuse = True
        with pytest.raises(Exception, match="exposure too short"):
            await process.post(["DET", "configure"], {"generator": compound(("x", 4))})
        assert (block.state.value, steps(block)) == ("Finished", (2, 2, 2))

    run(scenario)


def test_validate_waits_for_no_configure():
    async def scenario():
        part = Refuses("det")
        part.refuse = False
        process = Process()
        controller = RunnableController("DET", [part])
        process.add_controller(controller)
        await process.start()
        configuring = asyncio.ensure_future(
            process.post(["DET", "configure"], {"generator": compound(("x", 4))})
        )
        await part.entered.wait()  # the configure's own Validate is running
        with pytest.raises(NotAllowedError, match="configure is in progress"):
            await process.post(["DET", "validate"], {"generator": compound(("x", 2))})
        part.release.set()
        await configuring
        assert controller.block.state.value == "Armed"
        # once nothing runs, validate() works (and leaves the scan alone)
        out = await process.post(["DET", "validate"], {"generator": compound(("x", 2))})
        assert out["generator"]["generators"][0]["size"] == 2
        assert steps(controller.block) == (4, 0, 4)

    run(scenario)


# ---- item 7: what a Follower row expects after the manager's own change


def test_the_managers_own_change_of_a_followed_attribute_is_held_until_reset():
    """C.counter follows the manager's export Delta (C.delta). The manager's
    own put of C.counter is held; anyone else's is drift; reset follows
    Delta again."""

    async def scenario():
        process, manager = manager_of_counter(threaded=False)
        await process.start()
        await process.put(
            ["MGR", "exports"],
            {"name": ["Delta"], "source": ["C.delta"], "description": [""]},
        )
        await process.post(["MGR", "reset"])  # a table edit disables
        await process.put(
            ["MGR", "followers"], {"name": ["C.counter"], "source": ["Delta"]}
        )
        await process.post(["MGR", "reset"])
        child = process.get_block("CHILD")
        assert child.counter.value == 1.0  # it follows Delta
        await process.post(["MGR", "configure"], {"generator": compound(("x", 2))})
        assert (manager.current, manager.health.value) == ("Armed", "OK")
        assert child.counter.value == 5.0  # the manager's own put
        await process.put(["CHILD", "counter"], 7.0)
        assert manager.current == "Fault"
        assert manager.health.value == (
            "MGR: C.counter follows Delta: expected 5.0 (set by the manager;"
            " Delta is 1.0), but it is 7.0"
        )
        await process.post(["MGR", "reset"])
        assert (manager.current, manager.health.value) == ("Ready", "OK")
        assert child.counter.value == 1.0
        await process.stop()

    run(scenario)

"""Scan defects GDA would see (issue 7 items 3, 4 and 5), on live blocks."""

from __future__ import annotations

import asyncio
import gc

import pytest

from malcolm.controllers.runnable import RunnableController
from malcolm.core import PhaseTimeoutError, Process
from malcolm.demo import demo_generator, demo_process
from malcolm.fsm import RunnableDevice
from malcolm.parts import Part
from malcolm.parts.demo import RunnableChildPart, SimDetectorPart

from .scans import compound, run, steps


async def wait_for(predicate, timeout: float = 10.0) -> None:
    async with asyncio.timeout(timeout):
        while not predicate():
            await asyncio.sleep(0.002)


# ---- item 3: pause then resume of the demo SCAN


def test_demo_scan_pauses_and_resumes_to_the_end():
    async def scenario():
        process = demo_process()
        await process.start()
        scan = process.get_block("SCAN")
        generator = demo_generator(duration=0.02)
        await process.post(["SCAN", "configure"], {"generator": generator})
        pending = asyncio.ensure_future(process.post(["SCAN", "run"]))
        await wait_for(lambda: scan.completedSteps.value >= 3)
        await process.post(["SCAN", "pause"])
        assert scan.state.value == "Paused"
        # the children are back where their next call is allowed
        for det in ("DET1", "DET2"):
            assert process.get_block(det).resume.meta.writeable
        await process.post(["SCAN", "resume"])
        await pending
        assert (scan.state.value, scan.health.value) == ("Finished", "OK")
        assert scan.completedSteps.value == scan.totalSteps.value == 12
        for det in ("DET1", "DET2"):
            block = process.get_block(det)
            assert (block.state.value, block.framesTaken.value) == ("Finished", 12)
        await process.stop()

    run(scenario)


def test_demo_scan_pauses_twice_and_seeks_back_while_paused():
    async def scenario():
        process = demo_process()
        await process.start()
        scan = process.get_block("SCAN")
        await process.post(
            ["SCAN", "configure"], {"generator": demo_generator(duration=0.02)}
        )
        pending = asyncio.ensure_future(process.post(["SCAN", "run"]))
        for at in (3, 7):
            await wait_for(lambda at=at: scan.completedSteps.value >= at)
            await process.post(["SCAN", "pause"])
            await process.put(["SCAN", "completedSteps"], at - 2)
            assert process.get_block("DET1").completedSteps.value == at - 2
            await process.post(["SCAN", "resume"])
        await pending
        assert scan.state.value == "Finished"
        await process.stop()

    run(scenario)


# ---- item 4: a run longer than the default phase timeout


def detector(**kwargs) -> tuple[Process, RunnableController]:
    process = Process()
    part = SimDetectorPart("det", default_exposure=0.01)
    controller = RunnableController("DET", [part], **kwargs)
    process.add_controller(controller)
    return process, controller


def test_the_default_phase_timeout_does_not_limit_a_run():
    async def scenario():
        # 20 steps of 0.01 s: four times the default timeout given here
        process, controller = detector(phase_timeout=0.05)
        await process.start()
        scan = compound(("x", 20), duration=0.01)
        await process.post(["DET", "configure"], {"generator": scan})
        await process.post(["DET", "run"])
        assert controller.block.state.value == "Finished"
        assert controller.timeout_of("Run") is None
        assert controller.timeout_of("Configure") == 0.05

    run(scenario)


def test_an_explicit_run_timeout_still_applies():
    async def scenario():
        process, controller = detector(phase_timeouts={"Run": 0.05})
        await process.start()
        scan = compound(("x", 20), duration=0.01)
        await process.post(["DET", "configure"], {"generator": scan})
        with pytest.raises(PhaseTimeoutError, match="Run phase timed out"):
            await process.post(["DET", "run"])
        assert controller.block.state.value == "Fault"

    run(scenario)


class SlowRun(Part):
    @RunnableDevice.Run
    async def run(self, task, device):
        await asyncio.sleep(0.3)


def test_a_child_run_failing_after_its_manager_gave_up_is_not_lost():
    """The manager's run times out first and stops waiting for the child's
    run(); the child's run fails later. Nobody waits for that call any more:
    asyncio must not report an exception that was never retrieved."""
    lost: list[str] = []

    async def scenario():
        loop = asyncio.get_running_loop()
        loop.set_exception_handler(lambda _loop, ctx: lost.append(ctx["message"]))
        process = Process()
        child = RunnableController(
            "CHILD", [SlowRun("slow")], phase_timeouts={"Run": 0.1}
        )
        parent = RunnableController(
            "PARENT", [RunnableChildPart("c", "CHILD")], phase_timeouts={"Run": 0.02}
        )
        process.add_controller(child)
        process.add_controller(parent)
        await process.start()
        await process.post(["PARENT", "configure"], {"generator": compound(("x", 2))})
        with pytest.raises(PhaseTimeoutError):
            await process.post(["PARENT", "run"])
        await wait_for(lambda: child.block.state.value == "Fault")
        await process.stop()
        process = child = parent = None  # drop the last references to its call
        for _ in range(3):
            await asyncio.sleep(0.01)
            gc.collect()

    run(scenario)
    assert not [m for m in lost if "never retrieved" in m], lost


# ---- item 5: progress, pause(-1), pause(total)


class Gated(Part):
    """Reports each step of the run once allowed to."""

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.allowed = asyncio.Semaphore(0)

    @RunnableDevice.Run
    async def run(self, task, device):
        for step in range(device.completedSteps, device.configuredSteps):
            await self.allowed.acquire()
            task.report_progress(step + 1)


class PreRunOnly(Part):
    @RunnableDevice.PreRun
    async def prepare(self, task, device):
        return None


def gated_block() -> tuple[Process, RunnableController, Gated]:
    gate = Gated("gate")
    process = Process()
    controller = RunnableController("DET", [gate, PreRunOnly("prep")])
    process.add_controller(controller)
    return process, controller, gate


def test_a_part_whose_run_hooks_returned_does_not_hold_progress_back():
    async def scenario():
        process, controller, gate = gated_block()
        await process.start()
        block = controller.block
        await process.post(["DET", "configure"], {"generator": compound(("x", 6))})
        pending = asyncio.ensure_future(process.post(["DET", "run"]))
        for _ in range(3):
            gate.allowed.release()
        await wait_for(lambda: block.completedSteps.value == 3)
        assert block.state.value == "Running"
        for _ in range(3):
            gate.allowed.release()
        await pending
        assert steps(block) == (6, 6, 6)

    run(scenario)


@pytest.mark.parametrize("args", [{"lastGoodStep": -1}, {"completedSteps": -1}, {}])
def test_pause_at_a_negative_step_pauses_at_the_current_one(args):
    async def scenario():
        process, controller, gate = gated_block()
        await process.start()
        block = controller.block
        await process.post(["DET", "configure"], {"generator": compound(("x", 10))})
        pending = asyncio.ensure_future(process.post(["DET", "run"]))
        for _ in range(5):
            gate.allowed.release()
        await wait_for(lambda: block.completedSteps.value == 5)
        await process.post(["DET", "pause"], args)
        assert (block.state.value, steps(block)) == ("Paused", (10, 5, 10))
        await process.post(["DET", "abort"])
        with pytest.raises(Exception, match="aborted"):
            await pending

    run(scenario)


def test_pause_at_or_past_the_end_from_armed_goes_to_the_last_step():
    async def scenario():
        process, controller = detector()
        await process.start()
        block = controller.block
        await process.post(
            ["DET", "configure"],
            {"generator": compound(("y", 3), ("x", 2)), "axesToMove": ["x"]},
        )
        await process.post(["DET", "pause"], {"lastGoodStep": 6})
        assert (block.state.value, steps(block)) == ("Armed", (6, 5, 6))
        await process.post(["DET", "run"])
        assert (block.state.value, steps(block)) == ("Finished", (6, 6, 6))

    run(scenario)


@pytest.mark.parametrize("args", [{}, {"lastGoodStep": -1}, {"completedSteps": -5}])
def test_pause_at_the_current_step_of_a_finished_scan_goes_to_the_last_step(args):
    """The current step of a Finished scan is its end: as for a step past
    the end, the pause lands Armed on the last step (review A, F4)."""

    async def scenario():
        process, controller = detector()
        await process.start()
        block = controller.block
        params = {"generator": compound(("y", 3), ("x", 2)), "axesToMove": ["x"]}
        await process.post(["DET", "configure"], params)
        await process.put(["DET", "completedSteps"], 6)
        assert (block.state.value, steps(block)) == ("Finished", (6, 6, 6))
        await process.post(["DET", "pause"], args)
        assert (block.state.value, steps(block)) == ("Armed", (6, 5, 6))
        await process.post(["DET", "run"])
        assert (block.state.value, steps(block)) == ("Finished", (6, 6, 6))

    run(scenario)

"""The scan sequences of interop.md §1, on a live RunnableController."""

from __future__ import annotations

import asyncio
import threading

import pytest

from malcolm.controllers.runnable import RunnableController
from malcolm.core import AbortedError, BadValueError, NotAllowedError, Process
from malcolm.fsm import RunnableDevice
from malcolm.hooks import PhaseError
from malcolm.parts import Part
from malcolm.parts.demo import SimDetectorPart

from .scans import compound, run, steps


async def make(*parts: Part, **kwargs) -> tuple[Process, RunnableController, list]:
    process = Process()
    ctrl = RunnableController("DET", list(parts) or [SimDetectorPart("det")], **kwargs)
    process.add_controller(ctrl)
    states: list[str] = []
    process.subscribe(["DET", "state", "value"], states.append, delta=False)
    await process.start()
    return process, ctrl, states


def test_multi_run_with_axes_to_move():
    async def scenario():
        p, c, states = await make()
        b = c.block
        await p.post(["DET", "configure"], {"generator": compound(("y", 3), ("x", 2)),
                                            "axesToMove": ["x"]})  # fmt: skip
        assert (b.state.value, steps(b)) == ("Armed", (2, 0, 6))
        await p.post(["DET", "run"])
        assert (b.state.value, steps(b)) == ("Armed", (4, 2, 6))
        await p.post(["DET", "run"])
        assert (b.state.value, steps(b)) == ("Armed", (6, 4, 6))
        await p.post(["DET", "run"])
        assert (b.state.value, steps(b)) == ("Finished", (6, 6, 6))
        assert states[:5] == ["Disabled", "Resetting", "Ready", "Configuring", "Armed"]
        assert states[-3:] == ["Running", "PostRun", "Finished"]
        # Finished allows configure again
        await p.post(["DET", "configure"], {"generator": compound(("x", 3))})
        assert (b.state.value, steps(b)) == ("Armed", (3, 0, 3))

    run(scenario)


def test_breakpoints_cut_the_runs():
    async def scenario():
        p, c, _ = await make()
        b = c.block
        await p.post(["DET", "configure"], {"generator": compound(("x", 6)),
                                            "breakpoints": [2, 3, 1]})  # fmt: skip
        seen = [steps(b)]
        while b.state.value != "Finished":
            await p.post(["DET", "run"])
            seen.append(steps(b))
        assert seen == [(2, 0, 6), (5, 2, 6), (6, 5, 6), (6, 6, 6)]

    run(scenario)


def test_breakpoints_must_add_up_and_nothing_changes():
    async def scenario():
        p, c, _ = await make()
        with pytest.raises(BadValueError, match="add up to 4 but the scan has 6"):
            await p.post(["DET", "configure"], {"generator": compound(("x", 6)),
                                                "breakpoints": [2, 2]})  # fmt: skip
        assert c.block.state.value == "Ready"
        assert steps(c.block) == (0, 0, 0)

    run(scenario)


def test_bad_axes_to_move_is_an_error_naming_the_axis():
    async def scenario():
        p, c, _ = await make()
        with pytest.raises(BadValueError, match="z"):
            await p.post(["DET", "configure"], {"generator": compound(("x", 2)),
                                                "axesToMove": ["z"]})  # fmt: skip
        assert c.block.state.value == "Ready"

    run(scenario)


class GatedPart(Part):
    """Reports progress step by step, but each step waits for permission."""

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.allowed = asyncio.Semaphore(0)
        self.runs = 0

    @RunnableDevice.Run
    async def run(self, task, device):
        self.runs += 1
        for step in range(device.completedSteps, device.configuredSteps):
            await self.allowed.acquire()
            task.report_progress(step + 1)


async def wait_for(predicate, timeout=5.0):
    async with asyncio.timeout(timeout):
        while not predicate():
            await asyncio.sleep(0.001)


def test_pause_seek_resume():
    async def scenario():
        gate = GatedPart("gate")
        p, c, states = await make(gate)
        b = c.block
        await p.post(["DET", "configure"], {"generator": compound(("x", 10))})
        pending = asyncio.ensure_future(p.post(["DET", "run"]))
        for _ in range(5):
            gate.allowed.release()
        await wait_for(lambda: b.completedSteps.value == 5)
        # GDA sends lastGoodStep as completedSteps: both names work
        await p.post(["DET", "pause"], {"completedSteps": 3})
        assert (b.state.value, steps(b)) == ("Paused", (10, 3, 10))
        assert not pending.done()
        # seek while paused
        await p.put(["DET", "completedSteps"], 4)
        assert (b.state.value, steps(b)) == ("Paused", (10, 4, 10))
        await p.post(["DET", "resume"])
        for _ in range(6):
            gate.allowed.release()
        await pending  # the original run() completes the scan
        assert (b.state.value, steps(b)) == ("Finished", (10, 10, 10))
        assert gate.runs == 2
        assert "Seeking" in states and "Paused" in states

    run(scenario)


def test_pause_when_not_running_lands_armed_and_clamps():
    async def scenario():
        p, c, _ = await make()
        b = c.block
        await p.post(["DET", "configure"], {"generator": compound(("y", 3), ("x", 2)),
                                            "axesToMove": ["x"]})  # fmt: skip
        await p.post(["DET", "run"])
        await p.post(["DET", "pause"], {"lastGoodStep": 1})
        assert (b.state.value, steps(b)) == ("Armed", (2, 1, 6))
        # a seek put in Armed
        await p.put(["DET", "completedSteps"], 4)
        assert (b.state.value, steps(b)) == ("Armed", (6, 4, 6))
        # clamps to the last step of the scan, as the reference does
        await p.post(["DET", "pause"], {"lastGoodStep": 99})
        assert (b.state.value, steps(b)) == ("Armed", (6, 5, 6))
        # a seek put to the end finishes the scan
        await p.put(["DET", "completedSteps"], 6)
        assert (b.state.value, steps(b)) == ("Finished", (6, 6, 6))
        # from Finished back into the scan
        await p.post(["DET", "pause"], {"lastGoodStep": 2})
        assert (b.state.value, steps(b)) == ("Armed", (4, 2, 6))

    run(scenario)


def test_abort_makes_a_pending_run_fail():
    async def scenario():
        gate = GatedPart("gate")
        p, c, _ = await make(gate)
        await p.post(["DET", "configure"], {"generator": compound(("x", 10))})
        pending = asyncio.ensure_future(p.post(["DET", "run"]))
        await wait_for(lambda: c.block.state.value == "Running")
        await p.post(["DET", "abort"])
        assert c.block.state.value == "Aborted"
        with pytest.raises(AbortedError, match="run was aborted"):
            await pending
        await p.post(["DET", "reset"])
        assert c.block.state.value == "Ready"

    run(scenario)


def test_abort_while_paused_fails_the_run():
    async def scenario():
        gate = GatedPart("gate")
        p, c, _ = await make(gate)
        await p.post(["DET", "configure"], {"generator": compound(("x", 4))})
        pending = asyncio.ensure_future(p.post(["DET", "run"]))
        await wait_for(lambda: c.block.state.value == "Running")
        await p.post(["DET", "pause"])
        assert c.block.state.value == "Paused"
        await p.post(["DET", "abort"])
        with pytest.raises(AbortedError):
            await pending
        assert c.block.state.value == "Aborted"

    run(scenario)


class FailingPart(Part):
    def __init__(self, name: str, phase: str) -> None:
        super().__init__(name)
        self.phase = phase

    @RunnableDevice.Configure
    async def configure(self, task, device):
        if self.phase == "Configure":
            raise ValueError("the detector is on fire")

    @RunnableDevice.Run
    def run(self, task, device):  # a plain def: runs in a worker thread
        if self.phase == "Run":
            raise RuntimeError("lost the beam")


def test_an_exception_in_a_part_ends_in_fault_and_cancels_siblings():
    async def scenario():
        sibling_cancelled = asyncio.Event()

        class Sibling(Part):
            @RunnableDevice.Configure
            async def configure(self, task, device):
                try:
                    await asyncio.sleep(30)
                except asyncio.CancelledError:
                    sibling_cancelled.set()
                    raise

        p, c, _ = await make(FailingPart("bad", "Configure"), Sibling("slow"))
        with pytest.raises(PhaseError, match="Configure phase: part 'bad'"):
            await p.post(["DET", "configure"], {"generator": compound(("x", 2))})
        assert c.block.state.value == "Fault"
        assert "the detector is on fire" in c.block.health.value
        assert "bad" in c.block.health.value
        assert c.block.health.alarm.severity > 0
        assert sibling_cancelled.is_set()
        await p.post(["DET", "reset"])
        assert (c.block.state.value, c.block.health.value) == ("Ready", "OK")

    run(scenario)


def test_an_exception_in_a_threaded_part_during_run_ends_in_fault():
    async def scenario():
        p, c, _ = await make(FailingPart("bad", "Run"))
        await p.post(["DET", "configure"], {"generator": compound(("x", 2))})
        with pytest.raises(PhaseError, match="Run phase: part 'bad'.*lost the beam"):
            await p.post(["DET", "run"])
        assert c.block.state.value == "Fault"
        assert "RuntimeError: lost the beam" in c.block.health.value

    run(scenario)


def test_a_phase_timeout_ends_in_fault_naming_part_and_phase():
    class Stuck(Part):
        @RunnableDevice.Configure
        async def configure(self, task, device):
            await asyncio.Event().wait()

    async def scenario():
        p, c, _ = await make(Stuck("stuck"), phase_timeouts={"Configure": 0.05})
        with pytest.raises(TimeoutError):
            await p.post(["DET", "configure"], {"generator": compound(("x", 2))})
        assert c.block.state.value == "Fault"
        assert "Configure" in c.block.health.value
        assert "stuck" in c.block.health.value

    run(scenario)


def test_calls_the_model_does_not_allow_name_the_state_and_change_nothing():
    async def scenario():
        p, c, _ = await make()
        before = (c.block.state.value, steps(c.block), c.block.health.value)
        with pytest.raises(
            NotAllowedError, match=r"run\(\) is not allowed in state Ready"
        ):
            await p.post(["DET", "run"])
        with pytest.raises(NotAllowedError, match="state Ready"):
            await p.post(["DET", "resume"])
        with pytest.raises(NotAllowedError, match="state Ready"):
            await p.put(["DET", "completedSteps"], 1)
        assert (c.block.state.value, steps(c.block), c.block.health.value) == before

    run(scenario)


def test_parts_in_a_phase_run_concurrently_async_and_threaded():
    """Each part waits for the other: run one after the other, it would hang."""
    ready_a = asyncio.Event()
    ready_b = threading.Event()

    class A(Part):
        @RunnableDevice.Configure
        async def configure(self, task, device):
            ready_a.set()
            while not ready_b.is_set():
                await asyncio.sleep(0.001)

    class B(Part):
        @RunnableDevice.Configure
        def configure(self, task, device):
            ready_b.set()
            task.sleep(0.001)
            deadline = 500
            while not ready_a.is_set() and deadline:
                task.sleep(0.01)
                deadline -= 1
            assert ready_a.is_set()

    async def scenario():
        p, c, _ = await make(A("a"), B("b"), phase_timeout=10)
        await p.post(["DET", "configure"], {"generator": compound(("x", 2))})
        assert c.block.state.value == "Armed"

    run(scenario)


def test_validate_lets_parts_tweak_parameters_until_stable():
    from malcolm.core import NumberMeta

    class Exposure(Part):
        def setup(self, registrar):
            registrar.add_configure_arg(
                "exposure", NumberMeta("float64", "Exposure"), default=0.5
            )

        @RunnableDevice.Validate
        async def validate(self, task, device):
            if device.params["exposure"] > 0.1:
                return {"exposure": round(device.params["exposure"] / 2, 3)}

    async def scenario():
        p, c, _ = await make(Exposure("exp"))
        meta = c.block.configure.meta
        assert "exposure" in meta.takes.elements
        assert meta.defaults["exposure"] == 0.5
        out = await p.post(["DET", "validate"], {"generator": compound(("x", 2))})
        assert out["exposure"] == 0.062
        assert c.block.state.value == "Ready"

    run(scenario)


def test_validate_that_never_settles_is_an_error():
    class Flipper(Part):
        @RunnableDevice.Validate
        async def validate(self, task, device):
            return {"axesToMove": ["x"] if device.params.get("axesToMove") != ["x"]
                    else []}  # fmt: skip

    async def scenario():
        p, c, _ = await make(Flipper("flip"))
        with pytest.raises(BadValueError, match="did not settle"):
            await p.post(["DET", "validate"], {"generator": compound(("x", 2))})

    run(scenario)


def test_progress_is_the_minimum_over_parts():
    async def scenario():
        fast, slow = GatedPart("fast"), GatedPart("slow")
        p, c, _ = await make(fast, slow)
        await p.post(["DET", "configure"], {"generator": compound(("x", 6))})
        pending = asyncio.ensure_future(p.post(["DET", "run"]))
        for _ in range(4):
            fast.allowed.release()
        slow.allowed.release()
        await wait_for(lambda: c.block.completedSteps.value == 1)
        await asyncio.sleep(0.01)
        assert c.block.completedSteps.value == 1  # fast is at 4, slow at 1
        for _ in range(5):
            slow.allowed.release()
        for _ in range(2):
            fast.allowed.release()
        await pending
        assert c.block.completedSteps.value == 6

    run(scenario)


def test_a_scanspec_spec_configures_the_same_scan():
    from scanspec.specs import Line

    async def scenario():
        p, c, _ = await make()
        spec = Line("y", 0, 1, 3) * Line("x", 0, 1, 2)
        await p.post(["DET", "configure"], {"generator": spec, "axesToMove": ["x"]})
        assert (c.block.state.value, steps(c.block)) == ("Armed", (2, 0, 6))
        # the took log holds plain data a transport can send
        took = c.block.configure.took.to_dict()["value"]["generator"]
        assert took["type"] == "Product"
        await p.post(["DET", "run"])
        assert steps(c.block) == (4, 2, 6)

    run(scenario)


def test_configure_takes_the_scan_as_the_parts_validated_it():
    class InnerAxisOnly(Part):
        @RunnableDevice.Validate
        async def validate(self, task, device):
            if device.params.get("axesToMove") != ["x"]:
                return {"axesToMove": ["x"]}

    async def scenario():
        p, c, _ = await make(InnerAxisOnly("inner"), SimDetectorPart("det"))
        await p.post(["DET", "configure"], {"generator": compound(("y", 3), ("x", 2))})
        # a run does the x line only, as the part asked
        assert (c.block.state.value, steps(c.block)) == ("Armed", (2, 0, 6))
        assert c.device.params["axesToMove"] == ["x"]

    run(scenario)

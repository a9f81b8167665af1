"""One loop owns block state: def hooks' changes are run there, other threads
go through call_threadsafe, and the loop guard catches anything else."""

import os
import subprocess
import sys
import threading

import pytest

from malcolm.controllers.runnable import RunnableController
from malcolm.controllers.stateful import StatefulController
from malcolm.core import (
    AbortedError,
    NumberMeta,
    OffLoopError,
    Process,
    StringMeta,
    call_threadsafe,
    enable_loop_guard,
    loop_guard_enabled,
)
from malcolm.core.fields import Attribute
from malcolm.core.threads import guard_trips
from malcolm.embed import start_process
from malcolm.fsm import RunnableDevice
from malcolm.parts import Part
from malcolm.parts.demo import CounterPart

from .scans import compound, run


def counter_process() -> Process:
    process = Process("guarded")
    process.add_controller(StatefulController("C", [CounterPart("counter")]))
    return process


@pytest.fixture
def tp():
    tp = start_process(counter_process(), timeout=10)
    yield tp
    tp.stop(timeout=10)


def test_a_change_from_another_thread_raises_and_changes_nothing(tp):
    block = tp.process.get_block("C")
    seen = []
    tp.call_in_loop(tp.process.subscribe, ["C", "counter", "value"], seen.append, False)
    with pytest.raises(OffLoopError, match="C.counter was changed from thread"):
        block.counter.set_value(5.0)
    with pytest.raises(OffLoopError, match="C.delta"):
        block.delta.set_alarm(block.delta.alarm.invalid("x"))
    with pytest.raises(OffLoopError, match="C.extra"):
        block.add(Attribute("extra", StringMeta()))
    with pytest.raises(OffLoopError, match="the subscriptions of C.counter"):
        tp.process.subscribe(["C", "counter"], print)
    with pytest.raises(OffLoopError, match="the blocks of process 'guarded'"):
        tp.process.add_controller(StatefulController("D"))
    assert tp.process.mris == ["C"]
    assert block.counter.value == 0.0 and "extra" not in block
    assert tp.get(["C", "counter", "value"]) == 0.0
    assert seen == [0.0]
    guard_trips.clear()  # tripped on purpose


def test_call_threadsafe_is_the_path_from_other_threads(tp):
    block = tp.process.get_block("C")
    threads = []
    tp.call_in_loop(
        tp.process.subscribe,
        ["C", "counter", "value"],
        lambda v: threads.append(threading.current_thread()),
        False,
    )

    def library_thread():
        tp.process.call_threadsafe(block.counter.set_value, 7.0).result(5)

    worker = threading.Thread(target=library_thread)
    worker.start()
    worker.join(10)
    assert block.counter.value == 7.0
    assert threads and all(t is tp._thread for t in threads)


def test_call_threadsafe_on_the_loop_thread_runs_at_once():
    async def scenario():
        process = counter_process()
        await process.start()
        block = process.get_block("C")
        fut = process.call_threadsafe(block.counter.set_value, 3.0)
        assert fut.done() and block.counter.value == 3.0

        async def double():
            return block.counter.value * 2

        assert await asyncio_wrap(call_threadsafe(process.loop, double)) == 6.0

    run(scenario)


async def asyncio_wrap(fut):
    import asyncio

    return await asyncio.wrap_future(fut)


def test_call_threadsafe_needs_a_started_process():
    with pytest.raises(RuntimeError, match="has not been started"):
        counter_process().call_threadsafe(print)


class Stepper(Part):
    """A plain def Run hook that sets its own attribute from its worker thread."""

    def setup(self, registrar):
        self.steps = registrar.add_attribute("steps", NumberMeta("int32"), 0)

    @RunnableDevice.Run
    def run(self, task, device):
        for i in range(1, 4):
            self.steps.set_value(i)
        return threading.current_thread()


def test_a_def_hook_sets_an_attribute_and_subscribers_get_it_on_the_loop():
    async def scenario():
        process = Process()
        controller = RunnableController("DET", [Stepper("stepper")])
        process.add_controller(controller)
        await process.start()
        deliveries = []
        process.subscribe(
            ["DET", "steps", "value"],
            lambda v: deliveries.append((v, threading.current_thread())),
            delta=False,
        )
        await process.post(["DET", "configure"], {"generator": compound(("x", 1))})
        await process.post(["DET", "run"])
        worker = controller.device.part_info["Run"]["stepper"]
        return deliveries, worker

    deliveries, worker = run(scenario)
    main = threading.current_thread()
    assert worker is not main
    assert [v for v, _ in deliveries] == [0, 1, 2, 3]
    assert all(t is main for _, t in deliveries)


def test_the_guard_can_be_turned_off_and_on():
    assert loop_guard_enabled()  # tests/conftest.py turns it on
    enable_loop_guard(False)
    try:
        assert not loop_guard_enabled()
    finally:
        enable_loop_guard()
    assert loop_guard_enabled()


def test_the_environment_variable_turns_the_guard_on():
    code = "from malcolm.core import loop_guard_enabled; print(loop_guard_enabled())"
    out = {}
    for value in ("1", "0", ""):
        env = {**os.environ, "MALCOLM_LOOP_GUARD": value}
        result = subprocess.run(
            [sys.executable, "-c", code], env=env, capture_output=True, text=True
        )
        out[value] = result.stdout.strip()
    assert out == {"1": "True", "0": "False", "": "False"}


class Looper(Part):
    """A def Run hook setting its attribute until it is stopped."""

    def setup(self, registrar):
        self.steps = registrar.add_attribute("steps", NumberMeta("int32"), 0)
        self.ended = threading.Event()
        self.error = None

    @RunnableDevice.Run
    def run(self, task, device):
        try:
            for i in range(1, 10_000):
                self.steps.set_value(i)
                threading.Event().wait(0.005)
        except Exception as e:
            self.error = e
        finally:
            self.ended.set()


def test_a_def_hook_cannot_change_state_once_its_phase_is_aborted():
    part = Looper("looper")

    async def scenario():
        import asyncio

        process = Process()
        process.add_controller(RunnableController("DET", [part]))
        await process.start()
        await process.post(["DET", "configure"], {"generator": compound(("x", 1))})
        running = asyncio.ensure_future(process.post(["DET", "run"]))
        block = process.get_block("DET")
        while block.steps.value < 3:
            await asyncio.sleep(0.005)
        await process.post(["DET", "abort"])
        await asyncio.get_running_loop().run_in_executor(None, part.ended.wait, 10)
        with pytest.raises(AbortedError):
            await running
        return block.steps.value, block.state.value

    at_end, state = run(scenario)
    assert state == "Aborted"
    assert isinstance(part.error, AbortedError)
    assert part.steps.value == at_end

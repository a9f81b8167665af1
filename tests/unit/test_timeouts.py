"""One rule for every timeout of a method call or a put (docs/embedding.md):
the caller stops waiting and gets WaitTimeoutError saying the operation goes
on; the operation is never cancelled or undone. Issue 7 item 6.

Every slow operation here waits for a gate the test opens (no sleeps), and
the timeouts are short: nothing asserts how long anything took.
"""

import asyncio
import threading

import pytest

from malcolm.controllers.runnable import RunnableController
from malcolm.controllers.stateful import StatefulController
from malcolm.core import (
    AbortedError,
    BooleanMeta,
    MapMeta,
    NumberMeta,
    Process,
    WaitTimeoutError,
)
from malcolm.embed import start_process
from malcolm.fsm import RunnableDevice
from malcolm.hooks import FieldView
from malcolm.parts import Part

from .scans import compound

SHORT = 0.05
GOES_ON = "it goes on"


class Gate(Part):
    """``slow`` puts, ``wait()`` calls and DET's Run wait for ``gate`` to open."""

    def setup(self, registrar):
        self.opened = asyncio.Event()
        self.slow = registrar.add_attribute(
            "slow", NumberMeta("float64"), 0.0, put=self.put_slow
        )
        self.gate = registrar.add_attribute(
            "gate", BooleanMeta(), False, put=self.put_gate
        )
        self.waited = registrar.add_attribute("waited", NumberMeta("int32"), 0)
        registrar.add_method(self.wait, returns=MapMeta({"n": NumberMeta("int32")}))

    async def put_slow(self, value):
        await self.opened.wait()
        self.slow.set_value(value)

    def put_gate(self, value):
        self.gate.set_value(value)
        if value:
            self.opened.set()

    async def wait(self):
        """Return once the gate is open."""
        await self.opened.wait()
        self.waited.set_value(self.waited.value + 1)
        return {"n": self.waited.value}


class Runner(Part):
    """DET's Run waits for G's gate; Configure tries puts with timeouts."""

    @RunnableDevice.Run
    async def run(self, task, device):
        await task.when_matches(("G", "gate"), True)


def gate_process(*det_parts):
    process = Process("timeouts")
    process.add_controller(StatefulController("G", [Gate("gate")]))
    process.add_controller(RunnableController("DET", list(det_parts)))
    return process


@pytest.fixture
def tp():
    tp = start_process(gate_process(Runner("runner")), timeout=10)
    yield tp
    tp.stop(timeout=10)


# ---- the embedding facade


def test_a_call_that_times_out_goes_on_to_its_end(tp):
    det = tp.block("DET")
    det.configure(generator=compound(("x", 2)))
    with pytest.raises(WaitTimeoutError, match=GOES_ON):
        det.run.call(timeout=SHORT)
    assert det.state.value == "Running"
    tp.block("G").gate.put(True)
    assert det.state.when("Finished", timeout=10) == "Finished"


def test_a_method_that_times_out_is_not_cancelled(tp):
    g = tp.block("G")
    with pytest.raises(WaitTimeoutError, match=r"G.*wait.*it goes on"):
        g.wait.call(timeout=SHORT)
    g.gate.put(True)
    assert g.waited.when(1, timeout=10) == 1
    assert tp.get(["G", "wait", "returned", "value"]) == {"n": 1}


def test_a_put_that_times_out_completes(tp):
    g = tp.block("G")
    with pytest.raises(WaitTimeoutError, match=GOES_ON):
        g.slow.put(5, timeout=SHORT)
    g.gate.put(True)
    assert g.slow.when(5.0, timeout=10) == 5.0


def test_abort_is_what_stops_a_call(tp):
    det = tp.block("DET")
    det.configure(generator=compound(("x", 2)))
    running = det.run.future()
    with pytest.raises(WaitTimeoutError):
        det.state.when("Finished", timeout=SHORT)
    det.abort()
    with pytest.raises(AbortedError):
        running.result(10)


# ---- the Task API, async and blocking, and views


class Putter(Part):
    """At Configure: a put to G.slow that times out, in an async hook."""

    def __init__(self, name):
        super().__init__(name)
        self.errors = []

    @RunnableDevice.Configure
    async def configure(self, task, device):
        try:
            await task.put(("G", "slow"), 7, timeout=SHORT)
        except WaitTimeoutError as e:
            self.errors.append(e)


class BlockingPutter(Part):
    """The same from a plain def hook, through the task, a view and wait_all."""

    def __init__(self, name):
        super().__init__(name)
        self.errors = []

    @RunnableDevice.Configure
    def configure(self, task, device):
        view = FieldView(task.process, "G", "slow")
        for attempt in (
            lambda: task.put(("G", "slow"), 8, timeout=SHORT),
            lambda: view.put(9, timeout=SHORT),
            lambda: task.wait_all(task.put_async(("G", "slow"), 10), timeout=SHORT),
            lambda: FieldView(task.process, "G", "wait").call(timeout=SHORT),
        ):
            try:
                attempt()
            except WaitTimeoutError as e:
                self.errors.append(e)


@pytest.mark.parametrize("part", [Putter, BlockingPutter])
def test_task_puts_that_time_out_complete(part):
    putter = part("putter")
    tp = start_process(gate_process(putter), timeout=10)
    try:
        tp.block("DET").configure(generator=compound(("x", 1)))
        assert putter.errors and all(GOES_ON in str(e) for e in putter.errors)
        g = tp.block("G")
        assert g.slow.value == 0.0  # still waiting at the gate
        g.gate.put(True)
        # every put that timed out goes through the gate (none was cancelled)
        last = {Putter: 7.0, BlockingPutter: 10.0}[part]
        assert g.slow.when(last, timeout=10) == last
        if part is BlockingPutter:
            assert g.waited.when(1, timeout=10) == 1
    finally:
        tp.stop(timeout=10)


def test_a_view_put_from_a_plain_thread_that_times_out_completes(tp):
    process = tp.process
    errors = []

    def worker():
        try:
            FieldView(process, "G", "slow").put(4, timeout=SHORT)
        except WaitTimeoutError as e:
            errors.append(e)

    thread = threading.Thread(target=worker)
    thread.start()
    thread.join(10)
    assert len(errors) == 1 and GOES_ON in str(errors[0])
    tp.block("G").gate.put(True)
    assert tp.block("G").slow.when(4.0, timeout=10) == 4.0

"""Cancellation leaves nothing behind and reaches callers as malcolm errors."""

import asyncio

import pytest

from malcolm.controllers.runnable import RunnableController
from malcolm.controllers.stateful import StatefulController
from malcolm.core import AbortedError, Process, WaitTimeoutError
from malcolm.fsm import RunnableDevice
from malcolm.hooks import PhaseError
from malcolm.parts import Part
from malcolm.parts.demo import CounterPart

from .scans import compound, run


def test_blocking_wait_all_timeout_drops_its_waiters():
    errors = []

    class Waiter(Part):
        @RunnableDevice.Run
        def run(self, task, device):  # a plain def: a BlockingTask
            for i in range(3):
                try:
                    task.wait_all(
                        task.when_matches(("C", "counter"), 100 + i), timeout=0.02
                    )
                except WaitTimeoutError as e:
                    errors.append(e)

    async def scenario():
        p = Process()
        p.add_controller(StatefulController("C", [CounterPart("counter")]))
        p.add_controller(RunnableController("DET", [Waiter("w")]))
        await p.start()
        await p.post(["DET", "configure"], {"generator": compound(("x", 1))})
        await p.post(["DET", "run"])
        await asyncio.sleep(0.01)
        return len(p._subs.get("C", []))

    assert run(scenario) == 0
    assert len(errors) == 3


def test_a_hook_cancelled_from_outside_is_a_phase_error_not_cancelled_error():
    started = asyncio.Event()

    class Slow(Part):
        @RunnableDevice.Validate
        async def validate(self, task, device):
            started.set()
            await task.when_matches(("DET", "health"), "never", timeout=5)

    async def scenario():
        p = Process()
        c = RunnableController("DET", [Slow("slow")])
        p.add_controller(c)
        await p.start()
        pending = asyncio.ensure_future(
            p.post(["DET", "validate"], {"generator": compound(("x", 1))})
        )
        await started.wait()
        c.tasks["slow"].stop()  # what abort, reset and disable do
        with pytest.raises(PhaseError, match="Validate phase: part 'slow'"):
            await pending

    run(scenario)


def test_abort_stops_a_threaded_hook_writing_through_a_view():
    import time

    from malcolm.hooks import FieldView

    class Writer(Part):
        @RunnableDevice.Run
        def run(self, task, device):  # a plain def, writing through a view
            view = FieldView(task.process, "C", "counter")
            for i in range(1, 40):
                time.sleep(0.01)
                view.put(float(i))

    async def scenario():
        p = Process()
        p.add_controller(StatefulController("C", [CounterPart("counter")]))
        c = RunnableController("DET", [Writer("w")])
        p.add_controller(c)
        await p.start()
        await p.post(["DET", "configure"], {"generator": compound(("x", 1))})
        pending = asyncio.ensure_future(p.post(["DET", "run"]))
        counter = p.get_block("C").counter
        while counter.value < 3:
            await asyncio.sleep(0.005)
        await p.post(["DET", "abort"])
        at_abort = counter.value
        await asyncio.sleep(0.2)
        with pytest.raises(AbortedError):
            await pending
        return at_abort, counter.value

    at_abort, later = run(scenario)
    assert later == at_abort


def test_siblings_finish_their_clean_up_before_the_block_faults():
    cleaned = []

    class Tidy(Part):
        @RunnableDevice.Configure
        async def configure(self, task, device):
            try:
                await asyncio.sleep(30)
            finally:
                await asyncio.sleep(0.02)  # clean-up that itself awaits
                cleaned.append(True)

    class Bad(Part):
        @RunnableDevice.Configure
        async def configure(self, task, device):
            await asyncio.sleep(0.01)
            raise ValueError("broken")

    async def scenario():
        p = Process()
        c = RunnableController("DET", [Tidy("tidy"), Bad("bad")])
        p.add_controller(c)
        await p.start()
        with pytest.raises(PhaseError, match="broken"):
            await p.post(["DET", "configure"], {"generator": compound(("x", 1))})
        return list(cleaned), c.block.state.value

    assert run(scenario) == ([True], "Fault")

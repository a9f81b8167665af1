"""Futures that nobody waits for leave no "Task exception was never retrieved"
and no "coroutine ... was never awaited" behind (issue 7 item 6)."""

import asyncio
import gc
import logging
import warnings

import pytest

from malcolm.controllers.runnable import RunnableController
from malcolm.controllers.stateful import StatefulController
from malcolm.core import Process
from malcolm.fsm import RunnableDevice
from malcolm.hooks import FieldView
from malcolm.parts import Part
from malcolm.parts.demo import CounterPart

from .scans import compound, run

LEAKS = ("never retrieved", "never awaited")


def leaks(caplog, caught):
    gc.collect()
    texts = [r.getMessage() for r in caplog.records] + [str(w.message) for w in caught]
    return [t for t in texts if any(leak in t for leak in LEAKS)]


class FireAndForget(Part):
    @RunnableDevice.Configure
    async def configure(self, task, device):
        task.put_async(("C", "counter"), "not a number")  # fails; nobody waits
        await asyncio.sleep(0)


def test_a_failed_put_nobody_waits_for_is_not_reported_as_never_retrieved(caplog):
    async def scenario():
        p = Process()
        p.add_controller(StatefulController("C", [CounterPart("counter")]))
        p.add_controller(RunnableController("DET", [FireAndForget("f")]))
        await p.start()
        await p.post(["DET", "configure"], {"generator": compound(("x", 1))})
        for _ in range(3):
            await asyncio.sleep(0)
        return p.get_block("C").counter.value

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert run(scenario) == 0.0
        assert leaks(caplog, caught) == []


class Keeper(Part):
    """A def Configure hook that keeps its BlockingTask (its phase ends well)."""

    @RunnableDevice.Configure
    def configure(self, task, device):
        self.task = task


def test_calls_after_the_loop_has_gone_leave_no_coroutine(caplog):
    part = Keeper("keeper")

    async def scenario():
        p = Process()
        p.add_controller(StatefulController("C", [CounterPart("counter")]))
        p.add_controller(RunnableController("DET", [part]))
        await p.start()
        await p.post(["DET", "configure"], {"generator": compound(("x", 1))})
        return p

    caplog.set_level(logging.ERROR)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        process = run(scenario)  # the loop is closed when this returns
        task = part.task
        view = FieldView(process, "C", "counter")
        attempts = [
            lambda: task.put(("C", "counter"), 1),
            lambda: task.put_async(("C", "counter"), 2),
            lambda: task.when_matches(("C", "counter"), 3),
            lambda: view.put(4),
            lambda: FieldView(process, "C", "increment")(),
        ]
        for attempt in attempts:
            with pytest.raises(RuntimeError, match="closed|not been started"):
                attempt()
        assert leaks(caplog, caught) == []
    assert process.get_block("C").counter.value == 0.0

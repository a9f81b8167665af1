"""Task.put of one target with no timeout is awaited in place and
Task.wait_all of one future awaits it as it is: the same outcomes as the
general path (a Task per put, asyncio.wait) they skip: the put is made on
the task's behalf, its error is raised, cancelling the caller cancels the
put, and stop() still cancels a put_async nobody awaits."""

from __future__ import annotations

import asyncio
from typing import Any

import pytest

from malcolm.controllers.base import Controller
from malcolm.core import BadValueError, NumberMeta, Process
from malcolm.hooks import Task
from malcolm.hooks.origin import WRITER
from malcolm.parts import Part, PartRegistrar

from .scans import run


class Recorder(Part):
    """``slow``: its put waits for ``gate`` (and records being cancelled);
    ``fast``: records who wrote each value."""

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.gate = asyncio.Event()
        self.writers: list[str | None] = []
        self.cancelled = 0

    def setup(self, registrar: PartRegistrar) -> None:
        self.fast = registrar.add_attribute(
            "fast", NumberMeta("float64"), 0.0, put=self.put_fast
        )
        self.slow = registrar.add_attribute(
            "slow", NumberMeta("float64"), 0.0, put=self.put_slow
        )

    def put_fast(self, value: float) -> None:
        if value < 0:
            raise BadValueError("C.fast: no negative values")
        self.writers.append(WRITER.get())
        self.fast.set_value(value)

    async def put_slow(self, value: float) -> None:
        try:
            await self.gate.wait()
        except asyncio.CancelledError:
            self.cancelled += 1
            raise
        self.slow.set_value(value)


async def make(origin: str | None = "MGR") -> tuple[Process, Recorder, Task]:
    process = Process()
    part = Recorder("rec")
    process.add_controller(Controller("C", [part]))
    await process.start()
    return process, part, Task(process, "p", origin=origin)


def test_one_put_is_made_on_the_tasks_behalf():
    async def scenario():
        p, part, task = await make("MGR")
        await task.put(("C", "fast"), 1.0)
        assert p.get(["C", "fast", "value"]) == 1.0
        # without an origin: whoever runs the hook (here the context's)
        p2, part2, nobody = await make(None)
        token = WRITER.set("HOOK")
        try:
            await nobody.put(("C", "fast"), 2.0)
        finally:
            WRITER.reset(token)
        await nobody.put(("C", "fast"), 3.0)
        assert part.writers == ["MGR"]
        assert part2.writers == ["HOOK", None]
        assert WRITER.get() is None  # the task's origin does not stay set

    run(scenario)


def test_one_puts_error_is_raised():
    async def scenario():
        p, part, task = await make()
        with pytest.raises(BadValueError, match="no negative values"):
            await task.put(("C", "fast"), -1.0)
        with pytest.raises(BadValueError, match="no negative values"):
            await task.wait_all(task.put_async(("C", "fast"), -1.0))
        assert p.get(["C", "fast", "value"]) == 0.0

    run(scenario)


def test_cancelling_the_caller_cancels_the_put():
    async def scenario():
        p, part, task = await make()
        for call in (
            lambda: task.put(("C", "slow"), 5.0),
            lambda: task.wait_all(task.put_async(("C", "slow"), 5.0)),
        ):
            before = part.cancelled
            caller = asyncio.ensure_future(call())
            await asyncio.sleep(0.01)
            caller.cancel()
            await asyncio.wait({caller})
            await asyncio.sleep(0)
            assert part.cancelled == before + 1
        part.gate.set()
        await asyncio.sleep(0.01)
        assert p.get(["C", "slow", "value"]) == 0.0

    run(scenario)


def test_stop_cancels_a_put_nobody_awaits_and_the_wait_for_it():
    async def scenario():
        p, part, task = await make()
        fut = task.put_async(("C", "slow"), 5.0)
        waiting = asyncio.ensure_future(task.wait_all(fut))
        await asyncio.sleep(0.01)
        task.stop()
        await asyncio.wait({waiting})
        assert fut.cancelled()
        with pytest.raises(asyncio.CancelledError):
            waiting.result()
        assert part.cancelled == 1

    run(scenario)


def test_one_put_with_a_timeout_still_times_out():
    async def scenario():
        p, part, task = await make()
        from malcolm.core import WaitTimeoutError

        with pytest.raises(WaitTimeoutError):
            await task.put(("C", "slow"), 5.0, timeout=0.01)
        part.gate.set()  # the put went on
        for _ in range(100):
            if p.get(["C", "slow", "value"]) == 5.0:
                break
            await asyncio.sleep(0.01)
        assert p.get(["C", "slow", "value"]) == 5.0

    run(scenario)


def test_wait_all_of_one_gives_its_result_in_a_list():
    async def scenario():
        p, part, task = await make()
        loop = asyncio.get_running_loop()
        fut: asyncio.Future[Any] = loop.create_future()
        loop.call_later(0.01, fut.set_result, 42)
        assert await task.wait_all(fut) == [42]
        assert await task.wait_all([asyncio.sleep(0, result=7)]) == [7]

    run(scenario)

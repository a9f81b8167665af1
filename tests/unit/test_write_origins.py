"""Every write a part makes through its Task or its views of its children is
its manager's own (review A, F3): a manager does not trip its own Fixed row
when the write comes from a Task subscription callback told of someone
else's change, or from a thread a ``def`` hook starts itself."""

from __future__ import annotations

import asyncio
import threading
from typing import Any

import pytest

from malcolm.config.build import build_definition
from malcolm.controllers.runnable import RunnableController
from malcolm.controllers.stateful import StatefulController
from malcolm.core import Process
from malcolm.fsm import RunnableDevice
from malcolm.hooks import FieldView
from malcolm.hooks.origin import WRITER
from malcolm.parts import ChildPart
from malcolm.parts.demo import CounterPart

from .scans import compound, run

#: how a Run hook's subscription callback sets the motor's velocity
CALLBACK_WRITES = {
    "a view's put_async it returns": lambda part, task, v: (
        part.child.velocity.put_async(v)
    ),
    "a task.process put it returns": lambda part, task, v: task.process.put(
        [part.mri, "velocity"], v
    ),
    "a view's put_async it starts": lambda part, task, v: asyncio.ensure_future(
        part.child.velocity.put_async(v)
    ),
}


class FollowsTrigger(ChildPart):
    """During Run, sets the child motor's velocity to 20 + TRIG.counter
    whenever someone changes TRIG.counter (a block the manager does not
    hold), until the velocity is 21."""

    def __init__(self, name: str, mri: str, how: str) -> None:
        super().__init__(name, mri)
        self.how = how
        self.subscribed = asyncio.Event()

    @RunnableDevice.Run
    async def run(self, task, device) -> None:
        write = CALLBACK_WRITES[self.how]
        started: list[Any] = []

        def on_trigger(value: float) -> Any:
            if value > 0:
                result = write(self, task, 20.0 + value)
                if asyncio.isfuture(result):
                    started.append(result)
                    return None
                return result

        sid = task.subscribe(("TRIG", "counter"), on_trigger)
        self.subscribed.set()
        await task.when_matches(self.child.velocity, 21.0)
        await asyncio.gather(*started)
        task.unsubscribe(sid)


async def manager_of_a_motor(*parts: Any) -> Process:
    process = build_definition("demo.Motor", {"velocity": 50.0}, "M")
    process.add_controller(StatefulController("TRIG", [CounterPart("counter")]))
    process.add_controller(RunnableController("MGR", list(parts)))
    await process.start()
    await process.post(["MGR", "save"], {"design": "held"})  # M.velocity fixed
    return process


@pytest.mark.parametrize("how", list(CALLBACK_WRITES))
def test_a_write_from_a_task_subscription_callback_is_the_managers(how):
    async def scenario():
        part = FollowsTrigger("m", "M", how)
        process = await manager_of_a_motor(part)
        manager = process.get_controller("MGR")
        await process.post(["MGR", "configure"], {"generator": compound(("x", 2))})
        running = asyncio.ensure_future(process.post(["MGR", "run"]))
        await part.subscribed.wait()
        await process.put(["TRIG", "counter"], 1.0)  # an outside client
        await running
        assert (manager.current, manager.health.value) == ("Finished", "OK")
        assert process.get(["M", "velocity", "value"]) == 21.0
        # the row is live: anyone else's change of it is still drift
        await process.put(["M", "velocity"], 3.0)
        assert manager.current == "Fault"
        assert "velocity is fixed at 21.0" in manager.health.value
        await process.stop()

    run(scenario)


class PutsFromItsOwnThread(ChildPart):
    """A ``def`` Configure hook that starts a thread of its own, which puts
    the child motor's velocity through a view (from a new thread: none of
    the hook's context)."""

    def __init__(self, name: str, mri: str) -> None:
        super().__init__(name, mri)
        self.origins: list[str | None] = []

    @RunnableDevice.Configure
    def configure(self, task, device) -> None:
        errors: list[BaseException] = []

        def put() -> None:
            self.origins.append(WRITER.get())
            try:
                self.child.velocity.put(20.0)
            except BaseException as e:
                errors.append(e)

        thread = threading.Thread(target=put)
        thread.start()
        thread.join()
        if errors:
            raise errors[0]


def test_a_view_put_from_a_thread_a_def_hook_starts_is_the_managers():
    async def scenario():
        part = PutsFromItsOwnThread("m", "M")
        process = await manager_of_a_motor(part)
        manager = process.get_controller("MGR")
        await process.post(["MGR", "configure"], {"generator": compound(("x", 2))})
        assert part.origins == [None]  # the thread started with no origin
        assert (manager.current, manager.health.value) == ("Armed", "OK")
        assert process.get(["M", "velocity", "value"]) == 20.0
        await process.stop()

    run(scenario)


def test_a_view_with_no_origin_writes_as_whoever_uses_it():
    """A view made outside a part (embedding, tests) adds no origin: its put
    is anyone else's, so the manager's Fixed row faults."""

    async def scenario():
        process = await manager_of_a_motor(ChildPart("m", "M"))
        manager = process.get_controller("MGR")
        await FieldView(process, "M", "velocity").put_async(9.0)
        assert manager.current == "Fault"
        assert "velocity is fixed at 50.0, but it is 9.0" in manager.health.value
        await process.stop()

    run(scenario)

"""Puts and calls of the pvAccess server run on the loop, their first step
at once (malcolm.io.pva.ops): a Task is current (the runner's standing
Task, which an operation that waits keeps as its own), its context is the
Task's, and one that waits goes on without holding up the loop."""

from __future__ import annotations

import asyncio
import contextvars
import threading
import time
from typing import Any

import pytest
from p4p import Type, Value

from malcolm.io.pva.ops import OpRunner, start_op

from .p4p_monitor import monitor
from .test_pva_runtime import served  # noqa: F401 (a fixture)

VAR: contextvars.ContextVar[str] = contextvars.ContextVar("VAR", default="unset")


def from_callback(func: Any, *args: Any) -> Any:
    """``func(*args)`` run as a loop callback (no task current), as p4p's
    hand-over runs the handlers; awaitable for its result."""
    loop = asyncio.get_running_loop()
    fut = loop.create_future()
    loop.call_soon(lambda: fut.set_result(func(*args)))
    return fut


class Op:
    """What the runner needs of p4p's ServerOperation: done(value, error)."""

    def __init__(self) -> None:
        self.answers: list[tuple[Any, Any]] = []

    def done(self, value: Any = None, error: Any = None) -> None:
        self.answers.append((value, error))


class Runner:
    """The two ways to run an operation: OpRunner (the server's), and
    start_op (a Task per operation), with the same outcomes."""

    def __init__(self, kind: str) -> None:
        self.kind = kind
        self.runner = OpRunner()
        self.tasks = self.runner.tasks

    def start(self, op: Op, coro: Any) -> None:
        if self.kind == "runner":
            self.runner.start(op, coro)
        else:
            start_op(op, coro, self.tasks)


@pytest.fixture(params=["runner", "start_op"])
def kind(request: Any) -> str:
    return request.param


def test_an_operation_that_never_waits_is_answered_before_start_returns(kind):
    seen: list[Any] = []

    async def put(op: Op) -> None:
        seen.append(asyncio.current_task())
        op.done("ok")

    async def main() -> None:
        run = Runner(kind)
        op = Op()

        def handler() -> list[Any]:
            run.start(op, put(op))
            return list(op.answers)

        # answered with no turn of the loop
        assert await from_callback(handler) == [("ok", None)]
        assert not run.tasks
        assert isinstance(seen[0], asyncio.Task)
        await asyncio.sleep(0)
        if kind == "start_op":  # its own Task, ended as the operation did
            assert seen[0].done() and seen[0].exception() is None
        else:  # the standing Task, still waiting for the next operation
            assert not seen[0].done()
            run.runner.close()

    asyncio.run(main())


def test_operations_that_never_wait_make_no_task_each():
    """The runner's standing Task is current for each operation that ends
    at once: no Task is made per operation, none is left over."""
    seen: list[Any] = []

    async def put(op: Op) -> None:
        seen.append(asyncio.current_task())
        op.done("ok")

    async def main() -> None:
        runner = OpRunner()
        before = len(asyncio.all_tasks())
        for _ in range(5):
            op = Op()
            await from_callback(runner.start, op, put(op))
            assert op.answers == [("ok", None)]
        assert len(set(map(id, seen))) == 1  # one Task for all five
        assert len(asyncio.all_tasks()) == before + 1
        assert not runner.tasks
        runner.close()
        await asyncio.sleep(0)
        assert seen[0].cancelled()  # close() ends it
        assert len(asyncio.all_tasks()) == before

    asyncio.run(main())


def test_an_operation_that_waits_goes_on_in_its_task_with_its_context(kind):
    seen: dict[str, Any] = {}
    gate: list[asyncio.Future[None]] = []

    async def call(op: Op) -> None:
        token = VAR.set("mine")  # set in the first step...
        seen["first"] = asyncio.current_task()
        gate.append(asyncio.get_running_loop().create_future())
        await gate[0]
        seen["later"] = asyncio.current_task()
        seen["var"] = VAR.get()
        VAR.reset(token)  # ...reset after it: the same context
        op.done("answer")

    async def quick(op: Op) -> None:
        seen["next"] = asyncio.current_task()
        seen["next var"] = VAR.get()
        op.done("quick")

    async def main() -> None:
        run = Runner(kind)
        op, other = Op(), Op()
        await from_callback(run.start, op, call(op))
        assert op.answers == [] and len(run.tasks) == 1 and gate
        assert VAR.get() == "unset"  # the step ran in the Task's context
        # meanwhile another operation runs and ends, in a Task not the first's
        await from_callback(run.start, other, quick(other))
        assert other.answers == [("quick", None)]
        assert seen["next"] is not seen["first"] and seen["next var"] == "unset"
        gate[0].set_result(None)
        await asyncio.wait(set(run.tasks))
        assert op.answers == [("answer", None)]
        assert seen["first"] is seen["later"]
        assert seen["var"] == "mine"
        assert not run.tasks  # dropped once done
        run.runner.close()

    asyncio.run(main())


def test_a_variable_an_operation_leaves_set_is_not_seen_by_the_next():
    seen: list[tuple[Any, str]] = []

    async def leaves(op: Op) -> None:
        seen.append((asyncio.current_task(), VAR.get()))
        VAR.set("left")  # never reset
        op.done()

    async def main() -> None:
        runner = OpRunner()
        for _ in range(2):
            op = Op()
            await from_callback(runner.start, op, leaves(op))
        assert [var for _, var in seen] == ["unset", "unset"]
        assert seen[0][0] is not seen[1][0]  # its Task was not reused
        runner.close()

    asyncio.run(main())


def test_an_error_goes_to_the_client_as_its_type_and_message(kind):
    async def fails_at_once(op: Op) -> None:
        raise ValueError("bad at once")

    async def fails_later(op: Op) -> None:
        await asyncio.sleep(0)
        raise KeyError("bad later")

    async def main() -> None:
        run = Runner(kind)
        first, later = Op(), Op()
        await from_callback(run.start, first, fails_at_once(first))
        await from_callback(run.start, later, fails_later(later))
        assert first.answers == [(None, "ValueError: bad at once")]
        waiting = set(run.tasks)
        await asyncio.wait(waiting)
        assert later.answers == [(None, "KeyError: 'bad later'")]
        # answered, the Task ends as the operation would have returned
        assert all(t.exception() is None for t in waiting)
        run.runner.close()

    asyncio.run(main())


def test_an_operation_cancelled_while_waiting_is_cancelled_inside(kind):
    cancelled = threading.Event()

    async def call(op: Op) -> None:
        try:
            await asyncio.sleep(10)
        except asyncio.CancelledError:
            cancelled.set()
            raise

    async def main() -> None:
        run = Runner(kind)
        op = Op()
        await from_callback(run.start, op, call(op))
        (task,) = run.tasks
        task.cancel()
        await asyncio.wait({task})
        assert task.cancelled() and cancelled.is_set()
        run.runner.close()

    asyncio.run(main())


def test_close_cancels_the_operations_that_wait():
    cancelled = threading.Event()

    async def call(op: Op) -> None:
        try:
            await asyncio.sleep(10)
        except asyncio.CancelledError:
            cancelled.set()
            raise

    async def main() -> None:
        runner = OpRunner()
        op = Op()
        await from_callback(runner.start, op, call(op))
        (task,) = runner.tasks
        runner.close()
        await asyncio.wait({task})
        assert task.cancelled() and cancelled.is_set()

    asyncio.run(main())


def test_an_operation_started_in_a_task_runs_in_a_task_of_its_own():
    seen: list[Any] = []

    async def put(op: Op) -> None:
        seen.append(asyncio.current_task())
        op.done("ok")

    async def main() -> None:
        runner = OpRunner()
        op = Op()
        runner.start(op, put(op))  # from this task: not eager
        await asyncio.sleep(0)
        await asyncio.sleep(0)
        assert op.answers == [("ok", None)]
        assert seen[0] is not asyncio.current_task() and seen[0].done()
        runner.close()

    asyncio.run(main())


def test_a_call_that_sleeps_does_not_hold_up_other_clients(served):  # noqa: F811
    tp, process, server, ctx = served
    from p4p.client.thread import Context

    other = Context("pva", conf=ctx.conf(), useenv=False, nt=False)
    try:
        block = process.get_block("FIRST")
        assert ctx.get("FIRST.counter", timeout=5)["value"] == 0.0
        done: list[float] = []

        def slow_put() -> None:
            # a put whose handler waits: FIRST.counter's put waits for the
            # loop to let it through; here it is held by a gate below
            ctx.put("FIRST.counter", 5.0, timeout=10)
            done.append(time.monotonic())

        gate = process.call_threadsafe(asyncio.Event).result(5)
        controller = process.get_controller("FIRST")

        async def held_put(value: float) -> None:
            await gate.wait()
            block.counter.set_value(value)

        process.call_threadsafe(setattr, controller, "put_counter", held_put).result(5)
        worker = threading.Thread(target=slow_put)
        worker.start()
        time.sleep(0.3)
        assert not done  # still waiting at the gate
        # meanwhile another client is served at once
        assert other.get("FIRST.counter", timeout=5)["value"] == 0.0
        process.call_threadsafe(gate.set).result(5)
        worker.join(10)
        assert done
        assert other.get("FIRST.counter", timeout=5)["value"] == 5.0
        assert not server._tasks  # the put's task went when done
    finally:
        other.close()


def test_each_update_carries_only_its_own_change(served):  # noqa: F811
    """A channel builds every update in one Value (its marks cleared each
    time): an update never carries the fields of an earlier one, and the
    PV's current value, which a new client gets, has them all."""
    import queue

    tp, process, server, ctx = served
    updates: queue.Queue[Any] = queue.Queue()
    sub = monitor(ctx, "FIRST", updates.put, request="record[queueSize=10]")
    try:
        updates.get(timeout=10)  # the whole block
        block = process.get_block("FIRST")
        for attr, value in (("counter", 1.0), ("delta", 2.0), ("counter", 3.0)):
            process.call_threadsafe(getattr(block, attr).set_value, value).result(5)
            changed = updates.get(timeout=10).changedSet()
            other = "delta" if attr == "counter" else "counter"
            assert f"{attr}.value" in changed
            assert not any(c.startswith(f"{other}.") for c in changed), changed
        got = ctx.get("FIRST", timeout=5)
        assert (got["counter.value"], got["delta.value"]) == (3.0, 2.0)
        assert updates.empty()  # exactly one update per change
    finally:
        sub.close()


def test_changes_the_fast_path_recorded_are_in_the_channels_data(served):  # noqa: F811
    """The fast path records a change for the channel's data and applies it
    when the data is next read: a reshape after a run of changes (a whole
    field replaced among them) builds the new type from data that holds
    every one of them, and the data equals the process's."""
    from malcolm.core import Attribute, NumberMeta

    tp, process, server, ctx = served
    sub = monitor(ctx, "FIRST", lambda _value: None)
    try:
        ctx.get("FIRST", timeout=5)
        block = process.get_block("FIRST")
        chan = server._channels["FIRST"]

        async def changes() -> None:
            block.counter.set_value(1.0)
            block.delta.set_value(5.0)
            # the whole counter attribute, then its value again: later
            # changes below a replaced field land in the new field
            block.notify([[["counter"], block.counter.to_dict()]])
            block.counter.set_value(7.0)
            assert chan._pending  # recorded, not yet applied

        process.call_threadsafe(changes).result(5)
        expected = process.call_threadsafe(process.get, ["FIRST"]).result(5)

        def data() -> Any:
            got = chan.data
            return {k: v for k, v in got.items() if k != "meta"}

        got = process.call_threadsafe(data).result(5)
        assert got == {k: v for k, v in expected.items() if k != "meta"}
        assert not chan._pending
        process.call_threadsafe(block.add, Attribute("extra", NumberMeta("int32")))
        deadline = time.monotonic() + 10
        while "extra" not in (whole := ctx.get("FIRST", timeout=5)).keys():
            assert time.monotonic() < deadline
        assert (whole["counter.value"], whole["delta.value"]) == (7.0, 5.0)
    finally:
        sub.close()


def test_an_update_leaves_out_leaves_set_to_what_they_hold(served):  # noqa: F811
    """A change whose alarm and timeStamp seconds stay the same carries only
    what moved; after the channel's value was set another way (a whole
    replacement, not by the setters), a change back to what the setters
    last set still goes out, and a new client gets every value."""
    import queue

    tp, process, server, ctx = served
    updates: queue.Queue[Any] = queue.Queue()
    sub = monitor(ctx, "FIRST.counter", updates.put, request="record[queueSize=10]")
    try:
        updates.get(timeout=10)  # the whole field
        block = process.get_block("FIRST")
        process.call_threadsafe(block.counter.set_value, 1.0).result(5)
        updates.get(timeout=10)
        process.call_threadsafe(block.counter.set_value, 2.0).result(5)
        changed = updates.get(timeout=10).changedSet()
        assert "value" in changed and "timeStamp.nanoseconds" in changed
        assert not any(c.startswith("alarm") for c in changed), changed
        assert "timeStamp.userTag" not in changed

        async def replace() -> None:
            block.counter.value = 5.0  # the whole field, not by the setters
            block.notify([[["counter"], block.counter.to_dict()]])
            block.counter.set_value(2.0)  # what the setters last set

        process.call_threadsafe(replace).result(5)
        assert updates.get(timeout=10)["value"] == 5.0
        assert updates.get(timeout=10)["value"] == 2.0
        assert ctx.get("FIRST.counter", timeout=5)["value"] == 2.0
        got = ctx.get("FIRST.counter", timeout=5)
        assert got["alarm.severity"] == 0 and got["timeStamp.secondsPastEpoch"] > 0
        time.sleep(0.2)
        assert updates.empty()  # exactly one update per change
    finally:
        sub.close()


def test_a_call_reads_returns_applying_recorded_changes_only_there(served):  # noqa: F811
    """A call types its result by the method's returns in the channel's data:
    the changes the fast path recorded are applied first if one is at that
    path (the returns changed), not for a took or returned alone."""
    tp, process, server, ctx = served
    ctx.get("FIRST.zero", timeout=5)
    block = process.get_block("FIRST")
    chan = server._channels["FIRST.zero"]

    async def check() -> None:
        block.zero.set_took({})  # recorded by the fast path
        assert chan._pending
        before = chan._returns("FIRST", "zero")
        assert chan._pending  # left as it was
        returns = dict(before, required=["nothing"])  # a change that fits
        block.notify([[["zero", "meta", "returns"], returns]])
        assert ("meta", "returns") in chan._pending
        assert chan._returns("FIRST", "zero")["required"] == ["nothing"]
        assert not chan._pending  # applied for that

    process.call_threadsafe(check).result(5)


def test_a_client_that_has_its_answer_gets_the_new_took_and_returned(served):  # noqa: F811
    """A call is answered after its took and returned were posted: a get
    (answered by pvxs from its cache, in its own thread) of the method's or
    the block's channel right after the answer has this call's, every time;
    so does a new monitor's first update."""
    from p4p import Type, Value

    tp, process, server, ctx = served
    ctx.get("FIRST.zero", timeout=5)  # both channels open, answered from cache
    ctx.get("FIRST", timeout=5)
    empty = Value(Type([]), {})
    for _ in range(20):
        ctx.rpc("FIRST.zero", empty, timeout=5)
        took, returned = process.call_threadsafe(
            lambda: (
                process.get(["FIRST", "zero", "took", "timeStamp"]),
                process.get(["FIRST", "zero", "returned", "timeStamp"]),
            )
        ).result(5)
        field = ctx.get("FIRST.zero", timeout=5)
        block = ctx.get("FIRST", timeout=5)
        for got, prefix in ((field, ""), (block, "zero.")):
            for which, stamp in (("took", took), ("returned", returned)):
                where = f"{prefix}{which}.timeStamp"
                assert got[f"{where}.nanoseconds"] == stamp["nanoseconds"], where
                assert got[f"{where}.secondsPastEpoch"] == stamp["secondsPastEpoch"]
    import queue

    ctx.rpc("FIRST.zero", empty, timeout=5)
    stamp = process.call_threadsafe(
        process.get, ["FIRST", "zero", "returned", "timeStamp"]
    ).result(5)
    first: queue.Queue[Any] = queue.Queue()
    sub = monitor(ctx, "FIRST.zero", first.put)  # opened after the answer
    try:
        got = first.get(timeout=5)
        assert got["returned.timeStamp.nanoseconds"] == stamp["nanoseconds"]
    finally:
        sub.close()


def test_a_call_that_does_not_wait_is_one_update_of_took_and_returned(served):  # noqa: F811
    """The core publishes a call's took and returned as one batch when its
    method does not wait and publishes nothing else: a monitor of the
    method's channel and one of the block's each get one update holding
    both, equal to what the block keeps. A method that changes an attribute
    (FIRST.zero) has its took published first: two updates, took first."""
    import queue

    from p4p import Type, Value

    from malcolm.controllers.base import Controller
    from malcolm.parts.demo.hello import HelloPart

    tp, process, server, ctx = served

    async def add() -> None:
        controller = Controller("HI", [HelloPart("hello")])
        process.add_controller(controller)
        await controller.start()

    process.call_threadsafe(add).result(10)

    def stamps(method: str, mri: str) -> tuple[Any, Any]:
        return process.call_threadsafe(
            lambda: (
                process.get([mri, method, "took", "timeStamp"]),
                process.get([mri, method, "returned", "timeStamp"]),
            )
        ).result(5)

    for mri, method, args, batches in (
        ("HI", "greet", {"name": "me"}, [("took", "returned")]),
        ("FIRST", "zero", {}, [("took",), ("returned",)]),
    ):
        field: queue.Queue[Any] = queue.Queue()
        whole: queue.Queue[Any] = queue.Queue()
        request = "record[queueSize=10]"
        subs = [
            monitor(ctx, f"{mri}.{method}", field.put, request=request),
            monitor(ctx, mri, whole.put, request=request),
        ]
        try:
            field.get(timeout=10)  # the whole field
            whole.get(timeout=10)
            types = [(k, "s") for k in args]
            ctx.rpc(f"{mri}.{method}", Value(Type(types), args), timeout=5)
            took, returned = stamps(method, mri)
            stamp = {"took": took, "returned": returned}
            for updates, prefix in ((field, ""), (whole, f"{method}.")):
                for batch in batches:
                    update = updates.get(timeout=10)
                    while prefix and not any(  # the block's counter changes
                        c.startswith(prefix) for c in update.changedSet()
                    ):
                        update = updates.get(timeout=10)
                    changed = update.changedSet()
                    for which in ("took", "returned"):
                        where = f"{prefix}{which}.timeStamp.nanoseconds"
                        if which in batch:
                            assert update[where] == stamp[which]["nanoseconds"]
                        else:
                            assert where not in changed, (where, changed)
            time.sleep(0.2)
            assert field.empty()  # one update per batch
        finally:
            for sub in subs:
                sub.close()


def test_a_method_channel_answers_as_result_value_types_it_each_call(served):  # noqa: F811
    """A call on a method's channel with plain arguments is read in line and
    its result typed by result_value, then from its memo for results of the
    same keys and types while the returns meta is the same; a new returns
    meta is read and typed afresh; arguments that are not scalars still go
    through method_args."""
    from p4p import Type, Value

    from malcolm.controllers.base import Controller
    from malcolm.io.pva.results import result_value
    from malcolm.parts.demo.hello import HelloPart

    tp, process, server, ctx = served

    async def add() -> None:
        controller = Controller("HI", [HelloPart("hello")])
        process.add_controller(controller)
        await controller.start()

    process.call_threadsafe(add).result(10)
    args = Value(Type([("name", "s")]), {"name": "a"})
    got = [ctx.rpc("HI.greet", args, timeout=5) for _ in range(2)]
    chan = server._channels["HI.greet"]
    returns = process.call_threadsafe(lambda: chan.data["meta"]["returns"]).result(5)
    want = result_value({"greeting": "Hello a"}, returns)
    for answer in got:
        assert answer.type().aspy() == want.type().aspy()
        assert answer.todict() == want.todict()
    assert chan._memo and chan._memo[0] is returns
    block = process.get_block("HI")
    new = dict(returns, required=[])  # a change that fits: a new object

    async def change() -> None:
        block.notify([[["greet", "meta", "returns"], new]])

    process.call_threadsafe(change).result(5)
    answer = ctx.rpc("HI.greet", args, timeout=5)
    assert answer["greeting"] == "Hello a"
    memo = chan._memo
    assert memo[0] is not returns and memo[0]["required"] == []
    with pytest.raises(RuntimeError, match="BadValueError"):
        ctx.rpc("HI.greet", Value(Type([("name", "as")]), {"name": ["x"]}), timeout=5)


def test_a_calls_logs_taken_as_they_are_reach_the_channels_data_as_plain_data(
    served,  # noqa: F811
):
    """The fast path takes a method's took and returned as the core's
    MethodLogs; the channel's data, when read, holds their plain data (the
    process's to_dict), for the block's and the method's channels, and a
    reshape after them (the general path) builds from that data."""
    from malcolm.core import Attribute, MethodLog, NumberMeta

    tp, process, server, ctx = served
    sub = monitor(ctx, "FIRST", lambda _value: None)
    try:
        ctx.get("FIRST", timeout=5)
        ctx.get("FIRST.zero", timeout=5)
        chans = [server._channels["FIRST"], server._channels["FIRST.zero"]]
        for _ in range(2):
            ctx.rpc("FIRST.zero", Value(Type([]), {}), timeout=5)

        def check() -> None:
            for chan in chans:
                assert any(type(v) is MethodLog for v in chan._pending.values())
                data = chan.data
                method = data["zero"] if chan is chans[0] else data
                want = process.get(["FIRST", "zero"])
                for log in ("took", "returned"):
                    assert method[log] == want[log]
                    assert type(method[log]) is dict, log
                assert not chan._pending

        process.call_threadsafe(check).result(5)
        ctx.rpc("FIRST.zero", Value(Type([]), {}), timeout=5)
        block = process.get_block("FIRST")
        process.call_threadsafe(block.add, Attribute("extra", NumberMeta("int32")))
        deadline = time.monotonic() + 10
        while "extra" not in (whole := ctx.get("FIRST", timeout=5)).keys():
            assert time.monotonic() < deadline
        took = process.call_threadsafe(process.get, ["FIRST", "zero", "took"]).result(5)
        stamp = took["timeStamp"]
        assert whole["zero.took.timeStamp.nanoseconds"] == stamp["nanoseconds"]
        assert (
            whole["zero.took.timeStamp.secondsPastEpoch"] == stamp["secondsPastEpoch"]
        )
    finally:
        sub.close()

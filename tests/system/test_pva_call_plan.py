"""A served method's call plan: a meta changed at run time (in place, or
the method replaced as an Editor/Export change does) is used by the next
call over pvAccess, and what clients see of took/returned stays what the
process holds (an in-process server on free ports, a p4p client)."""

from __future__ import annotations

import queue
from typing import Any

import pytest
from p4p import Type, Value
from p4p.client.thread import Context, RemoteError

from malcolm.controllers.base import Controller
from malcolm.core import MapMeta, Method, MethodMeta, NumberMeta, Process, StringMeta
from malcolm.parts import Part

from .conftest import served_in_process
from .p4p_monitor import monitor


class Greeter(Part):
    def setup(self, registrar: Any) -> None:
        self.method = registrar.add_method(
            self.greet,
            returns=MapMeta({"greeting": StringMeta()}, ["greeting"]),
        )

    def greet(self, name: str, times: int = 1) -> dict[str, Any]:
        """Greet."""
        return {"greeting": f"hi {name}" * times}


@pytest.fixture
def served():
    process = Process("plan")
    part = Greeter("p")
    process.add_controller(Controller("G", [part]))
    with served_in_process(process) as (_, _, ctx):
        yield process, part, ctx


def _call(ctx: Context, channel: str, **args: Any) -> Any:
    fields = [(k, "s" if isinstance(v, str) else "l") for k, v in args.items()]
    return ctx.rpc(channel, Value(Type(fields), args), timeout=5)


def _settled(updates: queue.Queue[Any], want: Any) -> Any:
    """The monitor's latest value once it equals ``want`` (by its todict)."""
    got = None
    for _ in range(50):
        try:
            got = updates.get(timeout=5)
        except queue.Empty:
            break
        if not isinstance(got, Exception) and want(got):
            return got
    raise AssertionError(f"never settled: {got}")


def test_a_served_call_uses_a_meta_changed_at_run_time(served):
    process, part, ctx = served
    assert _call(ctx, "G.greet", name="a")["greeting"] == "hi a"
    updates: queue.Queue[Any] = queue.Queue()
    sub = monitor(ctx, "G.greet", updates.put)
    block_updates: queue.Queue[Any] = queue.Queue()
    block_sub = monitor(ctx, "G", block_updates.put)
    try:
        # a default changed in place: the next call takes it
        process.call_threadsafe(
            part.method.meta.defaults.__setitem__, "times", 2
        ).result(5)
        assert _call(ctx, "G.greet", name="b")["greeting"] == "hi bhi b"
        took = process.call_threadsafe(process.get, ["G", "greet", "took"]).result(5)
        assert took["value"] == {"name": "b", "times": 2}
        for q, prefix in ((updates, ""), (block_updates, "greet.")):
            got = _settled(
                q, lambda v, p=prefix: v[f"{p}returned.value.greeting"] == "hi bhi b"
            )
            assert got[f"{prefix}took.value.times"] == 2
            assert got[f"{prefix}took.value.name"] == "b"
            assert list(got[f"{prefix}took.present"]) == ["name", "times"]
            assert (
                got[f"{prefix}took.timeStamp.nanoseconds"]
                == took["timeStamp"]["nanoseconds"]
            )
        # the method replaced (as an Editor or Export change does): its
        # argument is now a number, and "times" unknown
        meta = MethodMeta(
            MapMeta({"name": NumberMeta("int32")}, ["name"]),
            MapMeta({"greeting": StringMeta()}),
        )

        def replace() -> None:
            block = process.get_block("G")
            block.remove("greet")
            block.add(Method("greet", meta, lambda name: {"greeting": f"#{name}"}))

        process.call_threadsafe(replace).result(5)
        for _ in range(50):  # the channel follows the new method
            try:
                result = _call(ctx, "G.greet", name=7)
                break
            except Exception:
                continue
        assert result["greeting"] == "#7"
        with pytest.raises(RemoteError, match=r"BadValueError: G.greet.name: expect"):
            _call(ctx, "G.greet", name="x")
        with pytest.raises(RemoteError, match=r"G.greet.times: unknown argument"):
            _call(ctx, "G.greet", name=1, times=1)
        got = ctx.get("G.greet", timeout=5)
        assert got["took.value.name"] == 7  # (the refused calls changed nothing)
        assert got["returned.value.greeting"] == "#7"
    finally:
        sub.close()
        block_sub.close()

"""A p4p client and a pvapy client of the served demo (interop.md §2): get
the whole block and one field, put a field both ways, call a method in each
form, see an error's text, receive monitor updates; and the structure of a
block, field for field, as §2 writes it."""

from __future__ import annotations

import os
import queue
import time
from typing import Any

import pytest
from p4p import Type, Value
from p4p.client.thread import RemoteError

from malcolm.io.pva.convert import to_dict

from .p4p_monitor import monitor

# ---- §2's structure of the demo's HELLO block, written down as data
CODES = {
    "s": "string",
    "?": "boolean",
    "i": "int",
    "l": "long",
    "d": "double",
    "as": "string[]",
    "v": "any",
    "av": "any[]",
}
ALARM = {"typeid": "alarm_t", "severity": "int", "status": "int", "message": "string"}
TIME = {
    "typeid": "time_t",
    "secondsPastEpoch": "long",
    "nanoseconds": "int",
    "userTag": "int",
}
DISPLAY = {
    "typeid": "display_t",
    "limitLow": "double",
    "limitHigh": "double",
    "description": "string",
    "precision": "int",
    "units": "string",
}


def meta(kind: str, **extra: Any) -> dict[str, Any]:
    return {
        "typeid": f"malcolm:core/{kind}:1.0",
        "description": "string",
        "tags": "string[]",
        "writeable": "boolean",
        "label": "string",
        **extra,
    }


def attribute(value: str, meta_: dict[str, Any]) -> dict[str, Any]:
    return {
        "typeid": "epics:nt/NTScalar:1.0",
        "value": value,
        "alarm": ALARM,
        "timeStamp": TIME,
        "meta": meta_,
    }


def map_meta(elements: dict[str, Any]) -> dict[str, Any]:
    return {
        "typeid": "malcolm:core/MapMeta:1.0",
        "elements": {"typeid": "structure", **elements},
        "required": "string[]",
    }


def method(takes: dict[str, Any], defaults: dict[str, str], returns: dict[str, Any]):
    def log(elements: dict[str, Any]) -> dict[str, Any]:
        value = {"typeid": "structure"}
        value.update({k: CODES[_value_code(m)] for k, m in elements.items()})
        return {
            "typeid": "malcolm:core/MethodLog:1.0",
            "value": value,
            "present": "string[]",
            "alarm": ALARM,
            "timeStamp": TIME,
        }

    return {
        "typeid": "malcolm:core/Method:1.1",
        "took": log(takes),
        "returned": log(returns),
        "meta": {
            "typeid": "malcolm:core/MethodMeta:1.1",
            "description": "string",
            "tags": "string[]",
            "writeable": "boolean",
            "label": "string",
            "takes": map_meta(takes),
            "defaults": {"typeid": "structure", **defaults},
            "returns": map_meta(returns),
        },
    }


def _value_code(m: dict[str, Any]) -> str:
    return {"StringMeta": "s", "NumberMeta": "d"}[m["typeid"].split("/")[1][:-4]]


STRING = meta("StringMeta")
FLOAT64 = meta("NumberMeta", dtype="string", display=DISPLAY)
HELLO = {
    "typeid": "malcolm:core/Block:1.0",
    "meta": {
        "typeid": "malcolm:core/BlockMeta:1.0",
        "description": "string",
        "tags": "string[]",
        "writeable": "boolean",
        "label": "string",
        "fields": "string[]",
    },
    "health": attribute("string", STRING),
    "state": attribute("string", meta("ChoiceMeta", choices="string[]")),
    "reset": method({}, {}, {}),
    "disable": method({}, {}, {}),
    "greet": method(
        {"name": STRING, "sleep": FLOAT64},
        {"sleep": "double"},
        {"greeting": STRING},
    ),
    "error": method({}, {}, {}),
}


def described(spec: Any) -> Any:
    """A p4p type spec (``Type.aspy()``) in the form of HELLO above."""
    if isinstance(spec, tuple) and spec[0] == "S":
        out = {"typeid": spec[1]}
        out.update({k: described(s) for k, s in spec[2]})
        return out
    return CODES.get(spec, spec)


# ---- p4p
def test_p4p_whole_block_matches_section_2(ctx):
    value = ctx.get("HELLO", timeout=5)
    assert described(value.type().aspy()) == HELLO
    assert list(value.keys()) == [
        "meta", "health", "state", "reset", "disable", "greet", "error",
    ]  # fmt: skip
    assert value["meta.fields"] == ["health", "state", "reset", "disable", "greet",
                                    "error"]  # fmt: skip
    tags = value["meta.tags"]
    assert any(t.startswith("version:malcolm:") for t in tags), tags
    assert value["greet.meta.defaults.sleep"] == 0.0
    assert value["greet.meta.takes.required"] == ["name"]


def test_p4p_scan_typeids(ctx):
    scan = ctx.get("SCAN", timeout=5)
    ids = {k: scan[k].getID() for k in scan.keys()}
    assert ids["completedSteps"] == "epics:nt/NTScalar:1.0"
    assert ids["simultaneousAxes"] == "epics:nt/NTScalarArray:1.0"
    assert ids["layout"] == "epics:nt/NTTable:1.0"
    assert ids["configure"] == "malcolm:core/Method:1.1"
    assert scan["layout"]["labels"] == ["Name", "Fullname", "X", "Y", "Visible"]
    assert scan["layout.meta"].getID() == "malcolm:core/TableMeta:1.0"
    assert scan["configure.meta.takes.elements.generator"].getID() == (
        "malcolm:core/PointGeneratorMeta:1.0"
    )
    assert scan["completedSteps.meta"].getID() == "malcolm:core/NumberMeta:1.0"
    assert scan["completedSteps.meta.dtype"] == "int32"
    assert dict(scan.type().aspy()[2])["completedSteps"][2][0] == ("value", "i")


def test_p4p_get_one_field(ctx):
    state = ctx.get("HELLO.state", timeout=5)
    assert state.getID() == "epics:nt/NTScalar:1.0"
    assert state["value"] == "Ready"
    assert state["meta"].getID() == "malcolm:core/ChoiceMeta:1.0"
    meta = ctx.get("HELLO.meta", timeout=5)
    assert meta.getID() == "malcolm:core/BlockMeta:1.0"


def test_p4p_put_both_ways(ctx):
    ctx.put("COUNTER.counter", 5, timeout=5)
    assert ctx.get("COUNTER.counter", timeout=5)["value"] == 5.0
    ctx.put("COUNTER", {"counter.value": 7}, request="counter.value", timeout=5)
    assert ctx.get("COUNTER", timeout=5)["counter.value"] == 7.0


def test_p4p_put_errors_name_what_and_where(ctx):
    before = ctx.get("COUNTER.counter", timeout=5)["value"]
    with pytest.raises(RemoteError, match=r"^NotWriteableError: .*HELLO.*state"):
        ctx.put("HELLO.state", "Fault", timeout=5)
    with pytest.raises(RemoteError, match=r"^NotAllowedError: .*completedSteps"):
        ctx.put("SCAN.completedSteps", 1, timeout=5)  # a seek, not when Ready
    with pytest.raises(RemoteError, match=r"^BadValueError: COUNTER.counter.alarm"):
        ctx.put("COUNTER", {"counter.alarm.message": "x"}, timeout=5)
    # unchanged (whatever earlier tests left)
    assert ctx.get("COUNTER.counter", timeout=5)["value"] == before


def greet_args(name: str) -> Value:
    return Value(Type([("name", "s")]), {"name": name})


def test_p4p_call_in_three_forms(ctx):
    # 1. the block's channel, the method in the pvRequest (what GDA sends)
    request = Value(Type([("method", "s")]), {"method": "greet"})
    got = ctx.rpc("HELLO", greet_args("one"), request=request, timeout=5)
    assert got["greeting"] == "Hello one"
    # 2. the method's channel
    got = ctx.rpc("HELLO.greet", greet_args("two"), timeout=5)
    assert got["greeting"] == "Hello two"
    # 3. an NTURI with path <mri>.<method>, arguments in query
    uri = Value(
        Type(
            [("scheme", "s"), ("path", "s"), ("query", ("S", None, [("name", "s")]))],
            id="epics:nt/NTURI:1.0",
        ),
        {"scheme": "pva", "path": "HELLO.greet", "query": {"name": "three"}},
    )
    assert ctx.rpc("HELLO", uri, timeout=5)["greeting"] == "Hello three"
    took = ctx.get("HELLO.greet", timeout=5)["took"]
    assert to_dict(took)["value"] == {"name": "three", "sleep": 0.0}


def test_p4p_error_text(ctx):
    with pytest.raises(RemoteError) as e:
        ctx.rpc("HELLO.error", Value(Type([]), {}), timeout=5)
    assert str(e.value) == "RuntimeError: You called method error()"
    with pytest.raises(RemoteError, match=r"^BadValueError: .*HELLO.greet.*name"):
        ctx.rpc("HELLO.greet", Value(Type([]), {}), timeout=5)
    with pytest.raises(RemoteError, match=r"^BadValueError: HELLO: .*method"):
        ctx.rpc("HELLO", greet_args("x"), timeout=5)  # no method named
    with pytest.raises(RemoteError, match=r"^NotFoundError: .*nothing"):
        request = Value(Type([("method", "s")]), {"method": "nothing"})
        ctx.rpc("HELLO", greet_args("x"), request=request, timeout=5)


def test_p4p_monitor_whole_then_what_changed(ctx, demo):
    updates: queue.Queue[Value] = queue.Queue()
    sub = monitor(ctx, "COUNTER", updates.put)
    try:
        first = updates.get(timeout=5)
        assert "counter.meta.description" in first.changedSet()
        for n in range(3):
            ctx.put("COUNTER.counter", 100 + n, timeout=5)
        later = [updates.get(timeout=5) for _ in range(3)]
        assert [u["counter.value"] for u in later] == [100.0, 101.0, 102.0]
        for u in later:
            changed = u.changedSet()
            assert "counter.value" in changed
            assert all(c.startswith("counter.") for c in changed), changed
            assert not any(c.startswith("counter.meta") for c in changed)
        time.sleep(0.2)
        assert updates.empty()  # exactly one update per change
    finally:
        sub.close()


# ---- pvapy (pvAccessCPP): configured through the environment
@pytest.fixture(scope="module")
def pvapy(demo):
    saved = {k: os.environ.get(k) for k in demo.conf}
    os.environ.update(demo.conf)
    import pvaccess

    yield pvaccess
    for k, v in saved.items():
        if v is None:
            os.environ.pop(k, None)
        else:
            os.environ[k] = v


def test_pvapy_get_block_and_field(pvapy):
    block = pvapy.Channel("HELLO").get("")
    assert list(block.keys())[:3] == ["meta", "health", "state"]
    assert block["state"]["value"] == "Ready"
    fields = block.getIntrospectionDict()["greet"]["meta"]["takes"]["elements"]
    assert set(fields) == {"name", "sleep"}
    state = pvapy.Channel("HELLO.state").get("")
    assert state["value"] == "Ready" and state["meta"]["choices"][1] == "Ready"


def test_pvapy_put_both_ways(pvapy):
    pvapy.Channel("COUNTER.counter").put(3.0)
    assert pvapy.Channel("COUNTER.counter").get("")["value"] == 3.0
    value = pvapy.PvObject(
        {"counter": {"value": pvapy.DOUBLE}}, {"counter": {"value": 9.0}}
    )
    pvapy.Channel("COUNTER").put(value, "counter.value")
    assert pvapy.Channel("COUNTER").get("")["counter"]["value"] == 9.0


def test_pvapy_calls_and_error(pvapy):
    # pvapy's RpcClient sends no pvRequest, so form 1 is p4p's only (above)
    args = pvapy.PvObject({"name": pvapy.STRING}, {"name": "pvapy"})
    got = pvapy.RpcClient("HELLO.greet").invoke(args, 5.0)
    assert got.toDict() == {"greeting": "Hello pvapy"}
    uri = pvapy.PvObject(
        {"scheme": pvapy.STRING, "path": pvapy.STRING, "query": {"name": pvapy.STRING}},
        {"scheme": "pva", "path": "HELLO.greet", "query": {"name": "uri"}},
        "epics:nt/NTURI:1.0",
    )
    assert pvapy.RpcClient("HELLO").invoke(uri, 5.0).toDict() == {
        "greeting": "Hello uri"
    }
    with pytest.raises(pvapy.PvaException) as e:
        pvapy.RpcClient("HELLO.error").invoke(pvapy.PvObject({}, {}), 5.0)
    assert str(e.value) == "RuntimeError: You called method error()"


def test_pvapy_monitor(pvapy, ctx):
    got: queue.Queue[Any] = queue.Queue()
    channel = pvapy.Channel("COUNTER.counter")
    channel.subscribe("test", lambda v: got.put(v["value"]))
    channel.startMonitor("")
    try:
        assert isinstance(got.get(timeout=5), float)
        ctx.put("COUNTER.counter", 42, timeout=5)
        deadline = time.monotonic() + 5
        while (v := got.get(timeout=5)) != 42.0:
            assert time.monotonic() < deadline, v
    finally:
        channel.stopMonitor()
        channel.unsubscribe("test")

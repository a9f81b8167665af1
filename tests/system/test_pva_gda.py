"""GDA's sequence over pvAccess against the served demo's SCAN (interop.md
§2): read state, health, meta and configure's defaults; validate, then
configure, with a CompoundGenerator structure as GDA builds it; monitor
state and completedSteps through run, pause, resume, abort and reset."""

from __future__ import annotations

import queue
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import pytest
from p4p import Type, Value
from p4p.client.thread import RemoteError

from malcolm.io.pva.convert import to_dict

from .p4p_monitor import monitor

SPG = "scanpointgenerator:generator"
LINE = Type(
    [
        ("axes", "as"),
        ("units", "as"),
        ("start", "ad"),
        ("stop", "ad"),
        ("size", "i"),  # GDA's numbers come as any int/float type
        ("alternate", "?"),
    ],
    id=f"{SPG}/LineGenerator:1.0",
)
COMPOUND = Type(
    [
        ("generators", "av"),
        ("excluders", "av"),
        ("mutators", "av"),
        ("duration", "f"),
        ("continuous", "?"),
        ("delay_after", "i"),
    ],
    id=f"{SPG}/CompoundGenerator:1.0",
)


def line(axis: str, size: int, alternate: bool = False) -> Value:
    return Value(
        LINE,
        {
            "axes": [axis],
            "units": ["mm"],
            "start": [0],
            "stop": [1],
            "size": size,
            "alternate": alternate,
        },
    )


def compound(duration: float) -> Value:
    return Value(
        COMPOUND,
        {
            "generators": [line("y", 3), line("x", 4, alternate=True)],
            "excluders": [],
            "mutators": [],
            "duration": duration,
            "continuous": True,
            "delay_after": 0,
        },
    )


def scan_args(duration: float) -> Value:
    args = Type([("generator", COMPOUND.aspy()), ("axesToMove", "as")], id="structure")
    value = Value(args, {"axesToMove": ["x"]})
    value["generator"] = compound(duration)
    return value


def call(ctx: Any, method: str, args: Value | None = None, timeout: float = 20):
    """GDA's form: the block's channel, the method's name in the pvRequest."""
    request = Value(Type([("method", "s")]), {"method": method})
    return ctx.rpc("SCAN", args or Value(Type([]), {}), request=request,
                   timeout=timeout)  # fmt: skip


def wait_for(updates: queue.Queue[Any], want: Any, seen: list[Any]) -> None:
    deadline = time.monotonic() + 20
    while True:
        seen.append(updates.get(timeout=max(0.0, deadline - time.monotonic())))
        if seen[-1] == want:
            return


def test_gda_reads(ctx):
    assert ctx.get("SCAN.state", timeout=5)["value"] == "Ready"
    assert ctx.get("SCAN.health", timeout=5)["value"] == "OK"
    meta = ctx.get("SCAN.meta", timeout=5)
    assert meta.getID() == "malcolm:core/BlockMeta:1.0"
    assert "configure" in meta["fields"]
    assert ctx.get("SCAN.simultaneousAxes", timeout=5).getID() == (
        "epics:nt/NTScalarArray:1.0"
    )
    configure = ctx.get("SCAN.configure", timeout=5)
    assert to_dict(configure["meta.defaults"]) == {"breakpoints": []}
    assert configure["meta.takes.required"] == ["generator"]


def test_negative_duration_is_refused_at_validate(ctx):
    with pytest.raises(RemoteError, match=r"^BadValueError: .*duration"):
        call(ctx, "validate", scan_args(-0.1))
    assert ctx.get("SCAN.state", timeout=5)["value"] == "Ready"


def test_gda_sequence(ctx):
    states: queue.Queue[str] = queue.Queue()
    steps: queue.Queue[int] = queue.Queue()
    subs = [
        monitor(ctx, "SCAN.state", lambda v: states.put(v["value"])),
        monitor(ctx, "SCAN.completedSteps", lambda v: steps.put(v["value"])),
    ]
    seen_states: list[str] = []
    seen_steps: list[int] = []
    try:
        wait_for(states, "Ready", seen_states)
        validated = call(ctx, "validate", scan_args(0.1))
        generator = to_dict(validated["generator"])
        assert generator["typeid"] == f"{SPG}/CompoundGenerator:1.0"
        assert [g["typeid"] for g in generator["generators"]] == [
            f"{SPG}/LineGenerator:1.0"
        ] * 2
        assert generator["duration"] == pytest.approx(0.1)
        assert list(validated["axesToMove"]) == ["x"]

        call(ctx, "configure", scan_args(0.1))
        wait_for(states, "Armed", seen_states)
        assert ctx.get("SCAN.totalSteps", timeout=5)["value"] == 12
        with ThreadPoolExecutor(1) as pool:
            running = pool.submit(call, ctx, "run")
            wait_for(states, "Running", seen_states)
            wait_for(steps, 1, seen_steps)
            call(ctx, "pause")
            wait_for(states, "Paused", seen_states)
            paused_at = ctx.get("SCAN.completedSteps", timeout=5)["value"]
            call(ctx, "resume")
            wait_for(states, "Running", seen_states)
            running.result(timeout=20)  # the run ends Armed after the row
        wait_for(states, "Armed", seen_states)
        assert ctx.get("SCAN.completedSteps", timeout=5)["value"] == 4
        with ThreadPoolExecutor(1) as pool:
            running = pool.submit(call, ctx, "run")
            wait_for(states, "Running", seen_states)
            call(ctx, "abort")
            with pytest.raises(RemoteError, match=r"^AbortedError"):
                running.result(timeout=20)
        wait_for(states, "Aborted", seen_states)
        call(ctx, "reset")
        wait_for(states, "Ready", seen_states)
    finally:
        for sub in subs:
            sub.close()
    while not steps.empty():
        seen_steps.append(steps.get())
    assert seen_states[:4] == ["Ready", "Configuring", "Armed", "Running"]
    assert "Paused" in seen_states and "Aborting" in seen_states
    assert 0 <= paused_at <= 4
    # completedSteps seen a step at a time to 4 (other updates carry its
    # meta, writeable or not with the state), then what the second run
    # reached before the abort; the monitor's last is the block's value
    values = [v for i, v in enumerate(seen_steps) if i == 0 or v != seen_steps[i - 1]]
    first_row = values[: values.index(4) + 1]
    assert first_row == list(range(5)), seen_steps
    assert seen_steps[-1] == ctx.get("SCAN.completedSteps", timeout=5)["value"]


def test_a_malformed_generator_is_refused_naming_where(ctx):
    bad = Value(
        Type([("generators", "av"), ("duration", "d")], id=COMPOUND.getID()),
        {"generators": [Value(Type([("size", "s")], id=f"{SPG}/Nothing:1.0"))]},
    )
    args = Value(Type([("generator", bad.type().aspy()), ("axesToMove", "as")]))
    args["generator"] = bad
    with pytest.raises(RemoteError, match=r"^BadValueError: .*generators\[0\]"):
        call(ctx, "validate", args)
    with pytest.raises(RemoteError, match=r"^BadValueError: .*SCAN.validate.*nope"):
        call(ctx, "validate", Value(Type([("nope", "i")]), {"nope": 1}))
    assert ctx.get("SCAN.state", timeout=5)["value"] == "Ready"  # still serving

"""A call's took and returned set by one pair function
(malcolm.io.pva.log_pair) mark and record what the two logs' setters and
the channel's fast path would, through any sequence of calls."""

from __future__ import annotations

import itertools
from typing import Any

import pytest
from p4p import Value

from malcolm.core import Alarm, MethodLog, TimeStamp
from malcolm.demo import demo_process
from malcolm.io.pva.convert import spec_at, to_value, type_spec
from malcolm.io.pva.log_pair import compile_log_pair
from malcolm.io.pva.setters import compile_setter


@pytest.fixture(scope="module")
def hello() -> dict[str, Any]:
    return demo_process().get(["HELLO"])


def marked(value: Value) -> dict[str, Any]:
    return {k: value[k] for k in sorted(value.changedSet())}


def _took() -> list[MethodLog]:
    major = Alarm.major("bad")
    both = ["name", "sleep"]
    return [
        MethodLog({"name": "a", "sleep": 0.0}, both, Alarm.ok, TimeStamp(5, 1)),
        MethodLog({"name": "a", "sleep": 0.0}, both, Alarm.ok, TimeStamp(5, 2)),
        MethodLog({"name": "a", "sleep": -0.0}, both, Alarm.ok, TimeStamp(5, 2)),
        MethodLog({"name": "b"}, ["name"], major, TimeStamp(6, 2)),
        MethodLog({"name": "b"}, ["name"], major, TimeStamp(6, 3, 2)),
        MethodLog({}, [], Alarm.ok, TimeStamp(7, 0)),
    ]  # fmt: skip


def _returned() -> list[MethodLog]:
    return [
        MethodLog({"greeting": "hi"}, ["greeting"], Alarm.ok, TimeStamp(5, 3)),
        MethodLog({"greeting": "hi"}, ["greeting"], Alarm.ok, TimeStamp(5, 4)),
        MethodLog({}, [], Alarm.major("no"), TimeStamp(6, 4)),
        MethodLog({}, [], Alarm.major("no"), TimeStamp(6, 5)),
    ]


@pytest.mark.parametrize("block", [True, False])
def test_the_pair_sets_what_the_two_log_setters_set(hello, block: bool) -> None:
    data = hello if block else hello["greet"]
    spec = type_spec(data)
    vtype = to_value(data).type()
    prefix: tuple[str, ...] = ("greet",) if block else ()
    took, returned = (*prefix, "took"), (*prefix, "returned")
    by_pair: dict[str, Any] = {}
    pending: dict[tuple[str, ...], Any] = {}
    pair = compile_log_pair(
        (spec_at(spec, took), took),
        (spec_at(spec, returned), returned),
        by_pair,
        pending,
    )
    assert pair is not None
    by_setters: dict[str, Any] = {}
    set_took = compile_setter(spec_at(spec, took), ".".join(took), last=by_setters)
    set_returned = compile_setter(
        spec_at(spec, returned), ".".join(returned), last=by_setters
    )
    moved = 0
    calls = list(itertools.product(_took(), _returned()))
    for t, r in calls + calls[::-1]:
        a, b = Value(vtype), Value(vtype)
        changes = [[["greet", "took"], t], [["greet", "returned"], r]]
        assert pair(a, changes)
        assert set_took(b, t) and set_returned(b, r)
        assert marked(a) == marked(b), (t, r)
        assert by_pair == by_setters
        assert list(pending) == [took, returned]
        assert pending[took] is t and pending[returned] is r
        moved += len(marked(a))
    assert moved > 40


def test_what_the_pair_does_not_take_it_refuses(hello) -> None:
    spec = type_spec(hello["greet"])
    vtype = to_value(hello["greet"]).type()
    ok = MethodLog({"greeting": "x"}, ["greeting"], Alarm.ok, TimeStamp(5, 1))
    for took in [
        MethodLog({"nobody": 1}, ["nobody"]),
        MethodLog({"name": 1}, ["name"]),
        MethodLog({"name": "x"}, ["name"], Alarm.ok, TimeStamp(5.5, 1)),  # type: ignore[arg-type]
        MethodLog({"name": "x"}, [1], Alarm.ok, TimeStamp(5, 1)),  # type: ignore[list-item]
        MethodLog({"name": "x"}, ["name"]).to_dict(),  # plain data
    ]:
        pair = compile_log_pair(
            (spec_at(spec, ("took",)), ("took",)),
            (spec_at(spec, ("returned",)), ("returned",)),
            {},
            {},
        )
        assert pair is not None
        changes = [[["greet", "took"], took], [["greet", "returned"], ok]]
        assert not pair(Value(vtype), changes), took


def test_a_pair_is_only_made_for_the_logs_the_core_makes(hello) -> None:
    spec = type_spec(hello)
    took = spec_at(spec, ("greet", "took"))
    assert compile_log_pair((took, ("t",)), (("S", "x", ()), ("r",)), {}, {}) is None
    assert compile_log_pair((took, ("t",)), ("d", ("r",)), {}, {}) is None

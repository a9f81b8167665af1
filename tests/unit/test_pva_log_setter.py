"""A MethodLog's setter given the core's MethodLog itself (what a method
publishes, malcolm.core.fields._new_log) marks and records the same leaves
as given its plain data, through any sequence of logs; the plain data of a
log reaches every other subscriber (and a channel's copy) as before."""

from __future__ import annotations

import asyncio
from typing import Any

import pytest
from p4p import Value

from malcolm.core import Alarm, MethodLog, TimeStamp
from malcolm.core.fields import _new_log, plain_changes
from malcolm.demo import demo_process
from malcolm.io.pva.convert import spec_at, to_value, type_spec
from malcolm.io.pva.setters import compile_setter


@pytest.fixture(scope="module")
def hello() -> dict[str, Any]:
    return demo_process().get(["HELLO"])


def marked(value: Value) -> dict[str, Any]:
    return {k: value[k] for k in sorted(value.changedSet())}


def _logs() -> list[MethodLog]:
    """A sequence of took logs: repeats, new arguments, fewer arguments, a
    float zero of each sign, alarms (equal but not the same object too),
    timeStamps moving and not."""
    major = Alarm.major("bad")
    return [
        MethodLog(
            {"name": "a", "sleep": 0.0}, ["name", "sleep"], Alarm.ok, TimeStamp(5, 1)
        ),
        MethodLog(
            {"name": "a", "sleep": 0.0}, ["name", "sleep"], Alarm.ok, TimeStamp(5, 2)
        ),
        MethodLog(
            {"name": "a", "sleep": -0.0}, ["name", "sleep"], Alarm.ok, TimeStamp(5, 2)
        ),
        MethodLog({"name": "b"}, ["name"], Alarm.ok, TimeStamp(6, 2)),
        MethodLog({"name": "b"}, ["name"], major, TimeStamp(6, 3)),
        MethodLog({"name": "b"}, ["name"], major, TimeStamp(6, 4)),
        MethodLog({"name": "b"}, ["name"], Alarm.major("bad"), TimeStamp(6, 5)),
        MethodLog({"name": "b"}, ["name"], Alarm.minor("meh"), TimeStamp(6, 5, 3)),
        MethodLog({"name": "b"}, ["name"], Alarm.ok, TimeStamp(6, 5, 3)),
        MethodLog({}, [], Alarm.ok, TimeStamp(7, 0)),
        MethodLog({"sleep": 1.5}, ["sleep"], Alarm.ok, TimeStamp(7, 0)),
    ]


def _setters(hello: dict[str, Any], last: dict[str, Any]) -> Any:
    spec = spec_at(type_spec(hello), ["greet", "took"])
    return compile_setter(spec, "greet.took", last=last)


def test_a_log_as_it_is_sets_what_its_plain_data_sets(hello):
    vtype = to_value(hello).type()
    by_object: dict[str, Any] = {}
    by_dict: dict[str, Any] = {}
    with_object, with_dict = _setters(hello, by_object), _setters(hello, by_dict)
    moved = 0
    for log in _logs():
        a, b = Value(vtype), Value(vtype)
        assert with_object(a, log)
        assert with_dict(b, log.to_dict())
        assert marked(a) == marked(b), log
        assert a.todict() == b.todict(), log
        moved += len(marked(a))
    assert moved > 10
    # their records differ only where the object's alarm is kept itself
    assert by_object.keys() == by_dict.keys()


def test_logs_of_either_kind_mixed_mark_what_moved(hello):
    """A setter given a MethodLog, then its plain data, then a MethodLog
    (a mirror's logs come as plain data): only what moved is marked."""
    vtype = to_value(hello).type()
    last: dict[str, Any] = {}
    setter = _setters(hello, last)
    log = MethodLog({"name": "x"}, ["name"], Alarm.major("m"), TimeStamp(5, 1))
    assert setter(Value(vtype), log)
    again = Value(vtype)
    assert setter(again, log.to_dict())
    assert marked(again) == {}
    ok = MethodLog({"name": "x"}, ["name"], Alarm.ok, TimeStamp(5, 2))
    value = Value(vtype)
    assert setter(value, ok)
    assert marked(value) == {
        "greet.took.alarm.message": "",
        "greet.took.alarm.severity": 0,
        "greet.took.alarm.status": 0,
        "greet.took.timeStamp.nanoseconds": 2,
    }
    value = Value(vtype)
    assert setter(value, ok.to_dict() | {"present": []})
    assert marked(value) == {"greet.took.present": []}
    value = Value(vtype)
    assert setter(value, ok)
    assert marked(value) == {"greet.took.present": ["name"]}


def test_a_log_that_does_not_fit_is_refused(hello):
    vtype = to_value(hello).type()
    setter = _setters(hello, {})
    for log in [
        MethodLog({"nobody": 1}, ["nobody"]),
        MethodLog({"name": 1}, ["name"]),
        MethodLog({"name": "x"}, ["name"], Alarm.ok, TimeStamp(5.5, 1)),  # type: ignore[arg-type]
    ]:
        assert not setter(Value(vtype), log), log
    # without a channel's record, the log's plain data is set
    spec = spec_at(type_spec(hello), ["greet", "took"])
    plain = compile_setter(spec, "greet.took")
    value = Value(vtype)
    assert plain(value, MethodLog({"name": "x"}, ["name"], Alarm.ok, TimeStamp(5, 1)))
    assert value["greet.took.value.name"] == "x"
    assert value["greet.took.timeStamp.secondsPastEpoch"] == 5


def test_a_log_of_scalars_is_published_as_it_is_others_as_plain_data():
    log, published = _new_log({"name": "x", "n": 1}, Alarm.ok)
    assert published is log
    assert log.present == ["name", "n"]
    items = [1, 2]
    log, published = _new_log({"items": items}, Alarm.ok)
    items.append(3)  # what the method keeps may change later: not the data
    assert published == {**log.to_dict(), "value": {"items": [1, 2]}}
    assert type(published) is dict


def test_plain_changes_replace_logs_and_keep_the_rest():
    log = MethodLog({"x": 1}, ["x"], Alarm.ok, TimeStamp(3, 4))
    other = [["f", "value"], 2]
    deleted = [["g"]]
    assert plain_changes([other, deleted]) == [other, deleted]
    out = plain_changes([other, [["m", "took"], log], deleted])
    assert out[0] is other and out[2] is deleted
    assert out[1] == [["m", "took"], log.to_dict()]
    assert type(out[1][1]) is dict


def test_subscribers_other_than_a_channel_get_a_calls_logs_as_plain_data():
    """Web, client mirrors, tests: each change of a call's took and returned
    is plain data, the method's logs' to_dict(); Process.get the same."""
    asyncio.run(_subscribers_get_plain_data())


async def _subscribers_get_plain_data() -> None:
    process = demo_process()
    await process.start()
    try:
        seen: list[Any] = []
        whole: list[Any] = []
        process.subscribe(["HELLO", "greet"], seen.append)
        process.subscribe(["HELLO", "greet"], whole.append, delta=False)
        seen.clear()
        whole.clear()
        await process.post(["HELLO", "greet"], {"name": "you"})
        method = process.get_block("HELLO").greet
        ((took, returned),) = seen
        assert took == [["took"], method.took.to_dict()]
        assert returned == [["returned"], method.returned.to_dict()]
        for _, data in (took, returned):
            assert type(data) is dict and type(data["value"]) is dict
        assert whole[-1] == process.get(["HELLO", "greet"])
        assert whole[-1]["returned"]["value"] == {"greeting": "Hello you"}
    finally:
        await process.stop()

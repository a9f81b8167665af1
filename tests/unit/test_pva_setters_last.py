"""A setter given its channel's ``last`` leaves a leaf it would set to what
it already holds unmarked (malcolm.io.pva.setters): an update carries only
the leaves that changed."""

from __future__ import annotations

import copy
from typing import Any

import pytest
from p4p import Value

from malcolm.demo import demo_process
from malcolm.io.pva.convert import spec_at, to_value, type_spec
from malcolm.io.pva.setters import compile_setter


@pytest.fixture(scope="module")
def hello() -> dict[str, Any]:
    return demo_process().get(["HELLO"])


def marked(value: Value) -> dict[str, Any]:
    return {k: value[k] for k in sorted(value.changedSet())}


def setter_of(data: dict[str, Any], path: list[str], last: dict[str, Any]) -> Any:
    return compile_setter(spec_at(type_spec(data), path), ".".join(path), last=last)


def test_a_method_log_set_again_marks_only_what_moved(hello):
    vtype = to_value(hello).type()
    last: dict[str, Any] = {}
    setter = setter_of(hello, ["greet", "took"], last)
    log = copy.deepcopy(hello["greet"]["took"])
    log["value"] = {"name": "x", "sleep": 1.5}
    log["present"] = ["name", "sleep"]
    log["timeStamp"] = {
        "typeid": "time_t",
        "secondsPastEpoch": 7,
        "nanoseconds": 1,
        "userTag": 0,
    }
    first = Value(vtype)
    assert setter(first, log)
    assert "greet.took.alarm.severity" in marked(first)
    assert marked(first)["greet.took.value.name"] == "x"
    log = copy.deepcopy(log)
    log["timeStamp"]["nanoseconds"] = 2
    again = Value(vtype)
    assert setter(again, log)
    assert marked(again) == {"greet.took.timeStamp.nanoseconds": 2}
    log = copy.deepcopy(log)
    log["value"]["name"] = "y"
    log["present"] = ["name"]
    moved = Value(vtype)
    assert setter(moved, log)
    assert marked(moved) == {
        "greet.took.value.name": "y",
        "greet.took.present": ["name"],
    }


def test_a_float_zero_is_always_set_and_a_cleared_last_sets_everything(hello):
    counter = demo_process().get(["COUNTER"])
    vtype = to_value(counter).type()
    last: dict[str, Any] = {}
    setter = setter_of(counter, ["counter", "value"], last)
    for data, expected in [
        (2.0, {"counter.value": 2.0}),
        (2.0, {}),  # what it holds already
        (2, {}),  # the same double
        (0.0, {"counter.value": 0.0}),
        (-0.0, {"counter.value": -0.0}),  # equal to 0.0, not the same
        (0, {"counter.value": 0.0}),  # an int zero after a float's
    ]:
        value = Value(vtype)
        assert setter(value, data)
        assert marked(value) == expected, data
    last.clear()  # what the channel does when it sets its value another way
    value = Value(vtype)
    assert setter(value, 0)
    assert marked(value) == {"counter.value": 0.0}


def test_two_setters_of_one_channel_share_what_they_set(hello):
    """A whole attribute's setter and its value's setter set one leaf: what
    one set, the other knows."""
    counter = demo_process().get(["COUNTER"])
    vtype = to_value(counter).type()
    last: dict[str, Any] = {}
    whole = setter_of(counter, ["counter"], last)
    leaf = setter_of(counter, ["counter", "value"], last)
    assert leaf(Value(vtype), 1.0)
    attribute = copy.deepcopy(counter["counter"])
    attribute["value"] = 5.0
    assert whole(Value(vtype), attribute)
    value = Value(vtype)
    assert leaf(value, 1.0)
    assert marked(value) == {"counter.value": 1.0}


def test_without_last_every_leaf_is_set_each_time(hello):
    vtype = to_value(hello).type()
    spec = spec_at(type_spec(hello), ["greet", "took"])
    setter = compile_setter(spec, "greet.took")
    log = hello["greet"]["took"]
    for _ in range(2):
        value = Value(vtype)
        assert setter(value, log)
        assert "greet.took.alarm.severity" in marked(value)


def test_a_structure_equal_to_the_one_last_set_is_skipped_whole(hello):
    """A structure of scalar leaves (an alarm, a method's arguments) equal
    to what was last set is passed over in one comparison; a float zero of
    the other sign, or a leaf set meanwhile by a setter of its own, still
    goes out."""
    vtype = to_value(hello).type()
    last: dict[str, Any] = {}
    log_setter = setter_of(hello, ["greet", "took"], last)
    severity = setter_of(hello, ["greet", "took", "alarm", "severity"], last)
    log = copy.deepcopy(hello["greet"]["took"])
    log["value"] = {"name": "x", "sleep": 0.0}
    log["present"] = ["name", "sleep"]
    assert log_setter(Value(vtype), log)
    assert "greet.took.alarm" in last and "greet.took.value" in last
    again = Value(vtype)
    assert log_setter(again, copy.deepcopy(log))
    assert marked(again) == {}  # nothing moved: not even the float zero
    log["value"]["sleep"] = -0.0  # equal to 0.0, not the same
    signed = Value(vtype)
    assert log_setter(signed, copy.deepcopy(log))
    assert marked(signed) == {"greet.took.value.sleep": -0.0}
    # a setter of one leaf of the alarm drops the alarm's record ...
    assert severity(Value(vtype), 2)
    assert "greet.took.alarm" not in last
    # ... so the alarm the log holds (severity 0) is set again
    back = Value(vtype)
    assert log_setter(back, copy.deepcopy(log))
    assert marked(back) == {"greet.took.alarm.severity": 0}


def test_a_timestamp_leaf_equal_to_what_it_holds_is_left_and_others_checked(hello):
    """A timeStamp's leaves (the core's ints) are compared to what they hold
    first: an equal one is left unmarked; a new one of the wrong type is
    still refused (the general path then takes the change)."""
    counter = demo_process().get(["COUNTER"])
    vtype = to_value(counter).type()
    last: dict[str, Any] = {}
    setter = setter_of(counter, ["counter", "timeStamp"], last)
    stamp = {"typeid": "time_t", "secondsPastEpoch": 5, "nanoseconds": 6, "userTag": 0}
    assert setter(Value(vtype), dict(stamp))
    value = Value(vtype)
    assert setter(value, {**stamp, "nanoseconds": 7})
    assert marked(value) == {"counter.timeStamp.nanoseconds": 7}
    assert not setter(Value(vtype), {**stamp, "nanoseconds": "8"})
    assert not setter(Value(vtype), {**stamp, "secondsPastEpoch": 5.5})

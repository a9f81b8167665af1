"""The compiled setters of monitor updates agree with convert's fits/assign
on the demo's real structures and on data that no longer fits."""

from __future__ import annotations

import copy
from typing import Any

import pytest
from p4p import Value

from malcolm.demo import demo_process
from malcolm.io.pva.convert import assign, fits, spec_at, to_value, type_spec
from malcolm.io.pva.setters import compile_setter


@pytest.fixture(scope="module")
def blocks() -> dict[str, Any]:
    process = demo_process()
    return {mri: process.get([mri]) for mri in process.mris}


def changed(value: Value) -> dict[str, Any]:
    return {k: value[k] for k in sorted(value.changedSet())}


def both(data: dict[str, Any], path: list[str], new: Any) -> tuple[Any, Any]:
    """(what fits/assign set, what the compiled setter set); None: no fit."""
    spec = type_spec(data)
    sub = spec_at(spec, path)
    vtype = to_value(data).type()
    expected = None
    if fits(sub, new):
        value = Value(vtype)
        assign(value, path, new, sub)
        expected = changed(value)
    value = Value(vtype)
    got = changed(value) if compile_setter(sub, ".".join(path))(value, new) else None
    return expected, got


def test_every_field_of_every_demo_block_sets_the_same_leaves(blocks):
    cases = 0
    for block in blocks.values():
        for field, data in block.items():
            if field in ("typeid", "meta") or not isinstance(data, dict):
                continue
            for key, sub in data.items():
                if key == "typeid":
                    continue
                expected, got = both(block, [field, key], copy.deepcopy(sub))
                assert got == expected, (field, key)
                assert expected is not None, (field, key)
                cases += 1
    assert cases > 50


def test_what_no_longer_fits_is_refused_as_fits_does(blocks):
    counter = blocks["COUNTER"]
    for path, new in [
        (["counter", "value"], "text"),  # a string in a double
        (["counter", "value"], True),  # a bool is not a number here
        (["counter", "value"], 2),  # an int fits a double
        (["counter", "timeStamp"], {"typeid": "time_t", "secondsPastEpoch": 1}),
        (["counter", "alarm"], {"typeid": "other", "severity": 0}),
        (["counter", "alarm"], [1, 2]),
    ]:
        expected, got = both(counter, path, new)
        assert got == expected, path
    assert both(counter, ["counter", "value"], "text") == (None, None)


def test_a_method_log_value_may_hold_fewer_arguments(blocks):
    hello = blocks["HELLO"]
    log = copy.deepcopy(hello["greet"]["took"])
    log["value"] = {}
    log["present"] = []
    expected, got = both(hello, ["greet", "took"], log)
    assert got == expected is not None
    log["value"] = {"nobody": "x"}
    assert both(hello, ["greet", "took"], log) == (None, None)


def test_a_result_is_typed_as_map_to_value_types_it_each_call(blocks):
    """result_value keeps the type of a result typed by its metas alone; the
    Value it gives is the one map_to_value builds, call after call, and a
    new returns meta (other elements) is typed afresh."""
    from malcolm.io.pva.convert import map_to_value
    from malcolm.io.pva.results import result_value

    returns = copy.deepcopy(blocks["HELLO"]["greet"]["meta"]["returns"])
    for name in ("a", "b"):
        result = {"greeting": f"Hello {name}"}
        got = result_value(result, returns)
        want = map_to_value(result, returns["elements"])
        assert got.type().aspy() == want.type().aspy()
        assert got.todict() == want.todict()
    other = copy.deepcopy(returns)
    other["elements"]["greeting"] = {"typeid": "malcolm:core/NumberMeta:1.0"}
    got = result_value({"greeting": 3}, other)
    assert got["greeting"] == 3.0 and got.type()["greeting"] == "d"
    # a key no meta describes: typed by what it holds, not kept
    got = result_value({"greeting": "x", "extra": [1, 2]}, returns)
    assert list(got["extra"]) == [1, 2]
    # the memo: a result of scalars its fields take as they are
    memo: list[Any] = []
    first = result_value({"greeting": "a"}, returns, memo)
    assert memo[0] is returns and memo[1] == (("greeting", str),)
    assert memo[2].aspy() == first.type().aspy()
    again = Value(memo[2], {"greeting": "b"})
    assert again.todict() == result_value({"greeting": "b"}, returns).todict()
    memo.clear()
    result_value({"greeting": "x", "extra": [1, 2]}, returns, memo)
    assert memo == []  # not all typed by metas: nothing to reuse


def test_a_structure_in_another_order_or_without_its_id_sets_the_same(blocks):
    """A plain dict of every field in order is unpacked in one step; one in
    another order, with fewer fields, without its typeid or of another id
    goes field by field and sets (or refuses) what fits/assign do."""
    hello = blocks["HELLO"]
    log = copy.deepcopy(hello["greet"]["took"])
    log["value"] = {"name": "x", "sleep": 0.5}
    log["present"] = ["name", "sleep"]
    full = both(hello, ["greet", "took"], copy.deepcopy(log))
    assert full[0] is not None and full[0] == full[1]
    variants = []
    reordered = dict(reversed(list(copy.deepcopy(log).items())))
    reordered["timeStamp"] = dict(reversed(list(reordered["timeStamp"].items())))
    variants.append(reordered)
    untyped = copy.deepcopy(log)
    del untyped["typeid"]
    variants.append(untyped)
    other = copy.deepcopy(log)
    other["timeStamp"]["typeid"] = "other_t"
    variants.append(other)
    fewer = copy.deepcopy(log)
    fewer["value"] = {"sleep": 0.5}  # fewer arguments: field by field
    variants.append(fewer)
    typed_args = copy.deepcopy(log)
    typed_args["value"] = {"typeid": "structure", "name": "y", "sleep": 1.0}
    variants.append(typed_args)
    results = [both(hello, ["greet", "took"], v) for v in variants]
    for expected, got in results:
        assert got == expected
    assert results[2] == (None, None)  # a timeStamp of another id
    assert results[3][0] is not None and results[4][0] is not None
    counter = blocks["COUNTER"]
    stamp = {"typeid": "time_t", "secondsPastEpoch": 3, "nanoseconds": 4.5}
    assert both(counter, ["counter", "timeStamp"], stamp) == (None, None)

"""Block.to_dict is the Malcolm structure of interop.md §2: typeids, names, order."""

import asyncio

from malcolm.controllers.stateful import StatefulController
from malcolm.core import (
    Alarm,
    Attribute,
    Block,
    BooleanArrayMeta,
    BooleanMeta,
    ChoiceArrayMeta,
    ChoiceMeta,
    MapMeta,
    Method,
    MethodMeta,
    NumberArrayMeta,
    NumberMeta,
    Process,
    StringArrayMeta,
    StringMeta,
    TableMeta,
    TimeStamp,
)
from malcolm.parts.demo import CounterPart

META_KEYS = ["typeid", "description", "tags", "writeable", "label"]
ALARM_KEYS = ["typeid", "severity", "status", "message"]
TIME_KEYS = ["typeid", "secondsPastEpoch", "nanoseconds", "userTag"]
LOG_KEYS = ["typeid", "value", "present", "alarm", "timeStamp"]


def _block() -> Block:
    block = Block("TEST", "A test block", ["version:malcolm:0.1"])
    block.add(Attribute("health", StringMeta("Health"), "OK"))
    block.add(Attribute("n", NumberMeta("int32", "A number", writeable=True), 3))
    block.add(Attribute("s", StringMeta("A string"), "x"))
    block.add(Attribute("b", BooleanMeta("A bool"), True))
    block.add(Attribute("c", ChoiceMeta(["a", "b"], "A choice"), "b"))
    block.add(Attribute("na", NumberArrayMeta("uint8", "Numbers"), [1, 2]))
    block.add(Attribute("sa", StringArrayMeta("Strings"), ["p"]))
    block.add(Attribute("ba", BooleanArrayMeta("Bools"), [False]))
    block.add(Attribute("ca", ChoiceArrayMeta(["a", "b"], "Choices"), ["a"]))
    table = TableMeta(
        {"x": NumberArrayMeta("float64", label="X"), "name": StringArrayMeta()},
        "A table",
    )
    block.add(Attribute("t", table, {"x": [1.5], "name": ["p"]}))
    takes = MapMeta({"a": NumberMeta("int32", "An a")}, ["a"])
    returns = MapMeta({"r": StringMeta("An r")})
    block.add(Method("go", MethodMeta(takes, returns, {"a": 1}, "Go")))
    return block


def test_block_structure():
    d = _block().to_dict()
    assert d["typeid"] == "malcolm:core/Block:1.0"
    fields = ["health", "n", "s", "b", "c", "na", "sa", "ba", "ca", "t", "go"]
    assert list(d) == ["typeid", "meta", *fields]
    assert d["meta"] == {
        "typeid": "malcolm:core/BlockMeta:1.0",
        "description": "A test block",
        "tags": ["version:malcolm:0.1"],
        "writeable": True,
        "label": "",
        "fields": fields,
    }


def test_scalar_attribute_structure():
    d = _block().to_dict()
    n = d["n"]
    assert list(n) == ["typeid", "value", "alarm", "timeStamp", "meta"]
    assert n["typeid"] == "epics:nt/NTScalar:1.0"
    assert n["value"] == 3
    assert list(n["alarm"]) == ALARM_KEYS and n["alarm"]["typeid"] == "alarm_t"
    assert list(n["timeStamp"]) == TIME_KEYS and n["timeStamp"]["typeid"] == "time_t"
    assert list(n["meta"]) == [*META_KEYS, "dtype", "display"]
    assert n["meta"]["typeid"] == "malcolm:core/NumberMeta:1.0"
    assert n["meta"]["dtype"] == "int32"
    assert n["meta"]["writeable"] is True
    assert n["meta"]["description"] == "A number"
    for name, typeid in [
        ("s", "StringMeta"),
        ("b", "BooleanMeta"),
        ("c", "ChoiceMeta"),
    ]:
        assert d[name]["typeid"] == "epics:nt/NTScalar:1.0"
        assert d[name]["meta"]["typeid"] == f"malcolm:core/{typeid}:1.0"
    assert list(d["s"]["meta"]) == META_KEYS
    assert d["c"]["meta"]["choices"] == ["a", "b"]


def test_array_attribute_structure():
    d = _block().to_dict()
    for name, typeid in [
        ("na", "NumberArrayMeta"),
        ("sa", "StringArrayMeta"),
        ("ba", "BooleanArrayMeta"),
        ("ca", "ChoiceArrayMeta"),
    ]:
        assert d[name]["typeid"] == "epics:nt/NTScalarArray:1.0"
        assert d[name]["meta"]["typeid"] == f"malcolm:core/{typeid}:1.0"
    assert d["na"]["value"] == [1, 2] and d["na"]["meta"]["dtype"] == "uint8"
    assert d["ca"]["meta"]["choices"] == ["a", "b"]


def test_table_attribute_structure():
    t = _block().to_dict()["t"]
    assert t["typeid"] == "epics:nt/NTTable:1.0"
    assert list(t) == ["typeid", "labels", "value", "alarm", "timeStamp", "meta"]
    assert t["labels"] == ["X", "name"]
    assert t["value"] == {
        "x": [1.5],
        "name": ["p"],
        "typeid": "malcolm:core/Table:1.0",
    }
    meta = t["meta"]
    assert meta["typeid"] == "malcolm:core/TableMeta:1.0"
    assert list(meta["elements"]) == ["x", "name"]
    assert meta["elements"]["x"]["typeid"] == "malcolm:core/NumberArrayMeta:1.0"


def test_method_structure():
    go = _block().to_dict()["go"]
    assert go["typeid"] == "malcolm:core/Method:1.1"
    assert set(go) == {"typeid", "took", "returned", "meta"}
    for log in (go["took"], go["returned"]):
        assert list(log) == LOG_KEYS
        assert log["typeid"] == "malcolm:core/MethodLog:1.0"
        assert log["alarm"]["typeid"] == "alarm_t"
        assert log["timeStamp"]["typeid"] == "time_t"
    meta = go["meta"]
    assert meta["typeid"] == "malcolm:core/MethodMeta:1.1"
    assert set(meta) == {*META_KEYS, "takes", "returns", "defaults"}
    assert meta["takes"] == {
        "typeid": "malcolm:core/MapMeta:1.0",
        "elements": {"a": NumberMeta("int32", "An a").to_dict()},
        "required": ["a"],
    }
    assert meta["returns"]["typeid"] == "malcolm:core/MapMeta:1.0"
    assert meta["returns"]["required"] == []
    assert meta["defaults"] == {"a": 1}


def test_method_log_after_a_call():
    block = _block()
    go = block.method("go")
    go.set_took({"a": 2})
    go.set_returned({"r": "done"}, Alarm.ok)
    d = go.to_dict()
    assert d["took"]["value"] == {"a": 2} and d["took"]["present"] == ["a"]
    assert d["returned"]["value"] == {"r": "done"}
    assert d["returned"]["timeStamp"]["secondsPastEpoch"] > 0


def test_number_display_defaults():
    display = NumberMeta("float32").to_dict()["display"]
    assert display == {
        "typeid": "display_t",
        "limitLow": 0.0,
        "limitHigh": 0.0,
        "description": "",
        "precision": 8,
        "units": "",
    }
    assert NumberMeta("int8").to_dict()["display"]["precision"] == 0
    units = NumberMeta(display={"units": "mm"}).to_dict()["display"]
    assert units["units"] == "mm"


def test_alarm_and_timestamp():
    assert Alarm.major("bad").to_dict() == {
        "typeid": "alarm_t",
        "severity": 2,
        "status": 1,
        "message": "bad",
    }
    assert TimeStamp(5, 6, 7).to_dict() == {
        "typeid": "time_t",
        "secondsPastEpoch": 5,
        "nanoseconds": 6,
        "userTag": 7,
    }


def test_field_order_is_meta_then_fields_as_added():
    block = Block("B")
    for name in ["z", "a", "m"]:
        block.add(Attribute(name, StringMeta()))
    assert list(block.to_dict()) == ["typeid", "meta", "z", "a", "m"]
    block.remove("a")
    block.add(Attribute("a", StringMeta()))
    block.add(Attribute("z", NumberMeta()))  # replacing keeps the place
    assert list(block.to_dict()) == ["typeid", "meta", "z", "m", "a"]
    assert block.meta.fields == ["z", "m", "a"]


def test_controller_block_starts_with_health():
    async def main():
        process = Process()
        process.add_controller(StatefulController("C", [CounterPart("counter")]))
        await process.start()
        d = process.get(["C"])
        await process.stop()
        return d

    d = asyncio.run(main())
    assert list(d)[:3] == ["typeid", "meta", "health"]
    assert d["meta"]["fields"] == list(d)[2:]
    assert d["state"]["value"] == "Ready"
    assert d["counter"]["meta"]["typeid"] == "malcolm:core/NumberMeta:1.0"
    assert d["increment"]["typeid"] == "malcolm:core/Method:1.1"

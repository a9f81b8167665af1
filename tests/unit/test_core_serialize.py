"""from_dict rebuilds what to_dict wrote; apply_changes applies deltas to data."""

import asyncio
import copy

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from malcolm.controllers.stateful import StatefulController
from malcolm.core import (
    Alarm,
    AlarmSeverity,
    AlarmStatus,
    Attribute,
    BadValueError,
    Block,
    BlockMeta,
    BooleanArrayMeta,
    BooleanMeta,
    ChoiceArrayMeta,
    ChoiceMeta,
    MapMeta,
    Method,
    MethodLog,
    MethodMeta,
    NotFoundError,
    NumberArrayMeta,
    NumberMeta,
    Process,
    StringArrayMeta,
    StringMeta,
    TableMeta,
    TimeStamp,
    apply_changes,
    from_dict,
    register_typeid,
    serialize,
    to_dict,
)
from malcolm.core.metas import DTYPES, FLOAT_DTYPES, INT_RANGES
from malcolm.core.serialize import build, registered_typeids
from malcolm.parts.demo import CounterPart

# ---- examples of every meta

EXAMPLE_METAS = [
    NumberMeta("int8"),
    NumberMeta("uint64", "big", ["widget:textinput"], True, "Big"),
    NumberMeta(
        "float32",
        "with display",
        display={"limitLow": -1.0, "limitHigh": 1.0, "units": "mm", "precision": 3},
    ),
    StringMeta("s", ["widget:textupdate", "group:g"], True, "S"),
    BooleanMeta("b", ["widget:led"]),
    ChoiceMeta(["a", "b", "c"], "c", writeable=True),
    ChoiceMeta([]),
    NumberArrayMeta("int16", "na", label="NA"),
    StringArrayMeta("sa"),
    BooleanArrayMeta("ba", writeable=True),
    ChoiceArrayMeta(["x", "y"], "ca"),
    TableMeta(
        {
            "x": NumberArrayMeta("float64", label="X"),
            "name": StringArrayMeta(),
            "on": BooleanArrayMeta(),
            "c": ChoiceArrayMeta(["p", "q"]),
        },
        "table",
        ["widget:table"],
        True,
        "T",
    ),
    MapMeta({"a": NumberMeta(), "b": StringArrayMeta()}, ["a"]),
    MapMeta(),
    MethodMeta(
        MapMeta({"a": NumberMeta("int32"), "t": StringArrayMeta()}, ["a"]),
        MapMeta({"r": StringMeta()}),
        {"t": ["x", "y"]},
        "method",
        ["method:hidden"],
        False,
        "M",
    ),
    MethodMeta(),
    BlockMeta("block", ["version:malcolm:0.1"], True, "B", ["health", "x"]),
]


@pytest.mark.parametrize("meta", EXAMPLE_METAS, ids=lambda m: type(m).__name__)
def test_every_meta_round_trips(meta):
    d = meta.to_dict()
    rebuilt = from_dict(d)
    assert type(rebuilt) is type(meta)
    assert rebuilt.to_dict() == d
    assert from_dict(copy.deepcopy(d)).to_dict() == d


def test_number_meta_display_is_rebuilt():
    meta = from_dict(EXAMPLE_METAS[2].to_dict())
    assert meta.dtype == "float32"
    assert meta.display["units"] == "mm" and meta.display["precision"] == 3
    assert "typeid" not in meta.display
    with pytest.raises(BadValueError, match="outside the limits"):
        meta.validate(2)


def test_table_meta_elements_are_rebuilt():
    meta = from_dict(EXAMPLE_METAS[11].to_dict())
    assert list(meta.elements) == ["x", "name", "on", "c"]
    assert isinstance(meta.elements["c"], ChoiceArrayMeta)
    assert meta.elements["c"].choices == ("p", "q")
    assert meta.elements["x"].label == "X"


def test_method_meta_is_rebuilt():
    meta = from_dict(EXAMPLE_METAS[14].to_dict())
    assert meta.takes.required == ("a",)
    assert meta.defaults == {"t": ["x", "y"]}
    assert meta.writeable is False
    assert meta.validate_args("m", {"a": "3"}) == {"a": 3, "t": ("x", "y")}


def test_alarm_timestamp_and_method_log():
    alarm = Alarm(AlarmSeverity.MINOR_ALARM, AlarmStatus.DRIVER_STATUS, "hm")
    assert from_dict(alarm.to_dict()) == alarm
    assert from_dict(TimeStamp(1, 2, 3).to_dict()) == TimeStamp(1, 2, 3)
    log = MethodLog({"a": [1, 2]}, ["a"], Alarm.major("x"), TimeStamp(4, 5))
    rebuilt = from_dict(log.to_dict())
    assert rebuilt == log
    assert rebuilt.to_dict() == log.to_dict()


# ---- attributes, methods, blocks


def test_attributes_round_trip():
    table = EXAMPLE_METAS[11]
    value = {"x": [1.0, 2.5], "name": ["a", "b"], "on": [1, 0], "c": ["q", 0]}
    attrs = [
        Attribute("n", NumberMeta("int32"), 5, Alarm.major("high"), TimeStamp(9, 8)),
        Attribute("s", StringMeta(), "hello"),
        Attribute("na", NumberArrayMeta("uint8"), [1, 2, 3]),
        Attribute("t", table, value),
    ]
    for attr in attrs:
        d = attr.to_dict()
        rebuilt = from_dict(d, attr.name)
        assert isinstance(rebuilt, Attribute)
        assert rebuilt.name == attr.name
        assert rebuilt.value == attr.value
        assert rebuilt.alarm == attr.alarm and rebuilt.timeStamp == attr.timeStamp
        assert rebuilt.to_dict() == d


def test_table_value_typeid_and_labels_are_dropped():
    d = Attribute("t", EXAMPLE_METAS[11], {"x": [1]}).to_dict()
    assert d["value"]["typeid"] == "malcolm:core/Table:1.0"
    rebuilt = from_dict(d, "t")
    assert "typeid" not in rebuilt.value
    assert rebuilt.value["x"] == (1.0,)


def test_method_round_trips_with_logs():
    method = Method("go", EXAMPLE_METAS[14])
    method.set_took({"a": 1, "t": ("x",)})
    method.set_returned({"r": "ok"}, Alarm.major("slow"))
    d = method.to_dict()
    rebuilt = from_dict(d, "go")
    assert isinstance(rebuilt, Method) and rebuilt.name == "go"
    assert rebuilt.took.value == {"a": 1, "t": ["x"]}
    assert rebuilt.returned.alarm == Alarm.major("slow")
    assert rebuilt.to_dict() == d


def _controller_block() -> dict:
    async def main():
        process = Process()
        process.add_controller(StatefulController("C", [CounterPart("counter")]))
        await process.start()
        await process.post(["C", "increment"])
        await process.put(["C", "delta", "value"], 2.5)
        d = process.get(["C"])
        await process.stop()
        return d

    return asyncio.run(main())


def test_whole_block_round_trips():
    d = _controller_block()
    block = from_dict(d, "C")
    assert isinstance(block, Block) and block.mri == "C"
    assert list(block) == d["meta"]["fields"]
    assert block.attribute("counter").value == 1.0
    assert block.attribute("delta").value == 2.5
    assert block.method("increment").took.timeStamp.secondsPastEpoch > 0
    assert block.to_dict() == d
    assert to_dict(block) == d


def test_block_with_every_kind_of_field_round_trips():
    block = Block("ALL", "all of them", ["version:x:1"])
    block.meta.label = "All"
    for i, meta in enumerate(EXAMPLE_METAS[:12]):
        block.add(Attribute(f"f{i}", meta))
    block.add(Method("m", EXAMPLE_METAS[14]))
    d = block.to_dict()
    rebuilt = from_dict(d, "ALL")
    assert rebuilt.to_dict() == d
    assert rebuilt.meta.label == "All"
    assert all(rebuilt[k].block is rebuilt for k in rebuilt)


# ---- errors name the typeid and the path


def _bad(d, message, name=""):
    with pytest.raises(BadValueError) as info:
        from_dict(d, name)
    assert str(info.value) == message
    assert type(info.value) is BadValueError


def test_unknown_typeid_names_the_path():
    d = _controller_block()
    d["counter"]["meta"]["typeid"] = "x"
    _bad(d, "counter.meta: unknown typeid 'x'")
    _bad({"typeid": "y"}, "top level: unknown typeid 'y'")


def test_errors_deep_inside():
    meta = EXAMPLE_METAS[14].to_dict()
    meta["takes"]["elements"]["t"]["typeid"] = "nope"
    _bad(meta, "takes.elements.t: unknown typeid 'nope'")

    d = Block("B").to_dict()
    d["meta"]["fields"] = ["t"]
    d["t"] = Attribute("t", EXAMPLE_METAS[11]).to_dict()
    del d["t"]["meta"]["elements"]["x"]["typeid"]
    _bad(d, "t.meta.elements.x: the structure has no typeid")
    d["t"]["meta"]["elements"]["x"] = StringMeta().to_dict()
    _bad(d, "t.meta.elements.x: a table column needs an array meta, not "
         "malcolm:core/StringMeta:1.0")  # fmt: skip


@pytest.mark.parametrize(
    "change, message",
    [
        (("meta", "dtype", "int7"), "n.meta: unknown dtype 'int7'"),
        (("meta", "tags", "x"), "n.meta.tags: expected a list or tuple, got 'x'"),
        (("meta", "tags", [1]), "n.meta.tags: expected strings, got [1]"),
        (("meta", "writeable", "yes"), "n.meta.writeable: expected a boolean"),
        (("meta", "display", 5), "n.meta.display: expected a structure, got 5"),
        (("value",), "n.value: expected a number (int32), got 'x'"),
        (("typeid",), "n: epics:nt/NTScalarArray:1.0 does not fit a"),
        (("meta",), "n.meta: expected a structure, got 'x'"),
        (("alarm", "severity", 9), "n.alarm: ValueError: 9 is not a valid"),
    ],
)
def test_bad_structures(change, message):
    d = Block("B").to_dict()
    d["meta"]["fields"] = ["n"]
    d["n"] = Attribute("n", NumberMeta("int32")).to_dict()
    if len(change) == 3:
        d["n"][change[0]][change[1]] = change[2]
    elif change == ("value",):
        d["n"]["value"] = "x"
    elif change == ("typeid",):
        d["n"]["typeid"] = "epics:nt/NTScalarArray:1.0"
    else:
        d["n"]["meta"] = "x"
    with pytest.raises(BadValueError) as info:
        from_dict(d)
    assert str(info.value).startswith(message)


def test_block_fields_must_match_meta_fields():
    d = Block("B").to_dict()
    d["x"] = Attribute("x", StringMeta()).to_dict()
    _bad(d, "meta.fields: lists [] but the block has fields ['x']")


def test_not_a_structure():
    _bad([1, 2], "top level: expected a structure, got [1, 2]")
    _bad({"description": "x"}, "top level: the structure has no typeid")


def test_a_field_where_a_meta_is_expected():
    d = Attribute("x", StringMeta()).to_dict()
    d["meta"] = Alarm().to_dict()
    _bad(d, "meta: not an attribute meta: Alarm(severity=<AlarmSeverity.NO_ALARM: 0>,"
         " status=<AlarmStatus.NO_STATUS: 0>, message='')")  # fmt: skip


# ---- the registry


def test_every_typeid_in_interop_is_registered():
    typeids = set(registered_typeids())
    for t in [
        "malcolm:core/Block:1.0",
        "malcolm:core/BlockMeta:1.0",
        "epics:nt/NTScalar:1.0",
        "epics:nt/NTScalarArray:1.0",
        "epics:nt/NTTable:1.0",
        "malcolm:core/Method:1.1",
        "malcolm:core/MethodMeta:1.1",
        "malcolm:core/MapMeta:1.0",
        "malcolm:core/MethodLog:1.0",
        "alarm_t",
        "time_t",
        *(
            f"malcolm:core/{m}Meta:1.0"
            for m in [
                "Number",
                "String",
                "Boolean",
                "Choice",
                "Table",
                "NumberArray",
                "StringArray",
                "BooleanArray",
                "ChoiceArray",
            ]
        ),
    ]:
        assert t in typeids


@pytest.fixture
def clean_registry():
    before = dict(serialize._REGISTRY)
    yield
    serialize._REGISTRY.clear()
    serialize._REGISTRY.update(before)


def test_register_a_typeid(clean_registry):
    @register_typeid("test:point:1.0")
    def point(d, path, name):
        if "x" not in d:
            raise BadValueError("needs x")
        return (d["x"], build(d["stamp"], (*path, "stamp")))

    stamp = {"typeid": "time_t", "secondsPastEpoch": 3}
    assert from_dict({"typeid": "test:point:1.0", "x": 1, "stamp": stamp}) == (
        1,
        TimeStamp(3),
    )
    _bad({"typeid": "test:point:1.0"}, "top level: needs x")
    _bad(
        {"typeid": "test:point:1.0", "x": 1, "stamp": {"typeid": "z"}},
        "stamp: unknown typeid 'z'",
    )
    with pytest.raises(ValueError, match="already registered"):
        register_typeid("test:point:1.0", lambda d, p, n: None)
    register_typeid("test:point:1.0", lambda d, p, n: "new", replace=True)
    assert from_dict({"typeid": "test:point:1.0"}) == "new"


def test_to_dict_convenience():
    assert to_dict(Alarm.ok) == Alarm.ok.to_dict()
    assert to_dict([TimeStamp(1), (1, 2)]) == [TimeStamp(1).to_dict(), [1, 2]]
    assert to_dict({"a": StringMeta()}) == {"a": StringMeta().to_dict()}
    assert to_dict(5) == 5


# ---- apply_changes


def test_apply_changes():
    data = {"a": {"b": 1, "c": [1]}, "d": 2}
    data = apply_changes(data, [[["a", "b"], 5], [["e"], {"f": 1}], [["d"]]])
    assert data == {"a": {"b": 5, "c": [1]}, "e": {"f": 1}}
    assert list(data) == ["a", "e"]
    assert apply_changes(data, [[[], 7]]) == 7
    assert apply_changes(data, [[[]]]) is None
    assert apply_changes(None, [[[], {"x": 1}], [["y"], 2]]) == {"x": 1, "y": 2}


def test_apply_changes_copies_values_in():
    value = {"x": [1]}
    data = apply_changes({}, [[["v"], value]])
    data["v"]["x"].append(2)
    assert value == {"x": [1]}


@pytest.mark.parametrize(
    "changes, message",
    [
        ([[["a", "b", "c"], 1]], "^change a.b.c: 'a.b' is not a structure"),
        ([[["z", "q"], 1]], "^change z.q: no 'z'"),
        ([[["z", "q", "r"]]], "^change z.q.r: no 'z'"),
        ([[["x"]]], "^change x: nothing to delete"),
    ],
)
def test_apply_changes_errors(changes, message):
    with pytest.raises(NotFoundError, match=message):
        apply_changes({"a": {"b": 1}}, changes)


def test_apply_changes_rejects_malformed():
    with pytest.raises(BadValueError, match="a change is"):
        apply_changes({}, [[["a"], 1, 2]])


# ---- property: any meta, any value, round trips

_text = st.text(st.characters(codec="utf-8", exclude_categories=["Cs"]), max_size=6)
_names = st.from_regex(r"[a-z][a-zA-Z0-9]{0,5}", fullmatch=True)


@st.composite
def _common(draw):
    return {
        "description": draw(_text),
        "tags": draw(st.lists(_text, max_size=3)),
        "writeable": draw(st.booleans()),
        "label": draw(_text),
    }


def _number_values(dtype):
    if dtype in FLOAT_DTYPES:
        width = 32 if dtype == "float32" else 64
        return st.floats(allow_nan=False, width=width)
    lo, hi = INT_RANGES[dtype]
    return st.integers(lo, hi)


@st.composite
def metas_and_values(draw, kinds=("n", "s", "b", "c", "na", "sa", "ba", "ca", "t")):
    kind = draw(st.sampled_from(kinds))
    common = draw(_common())
    if kind == "n":
        dtype = draw(st.sampled_from(DTYPES))
        display = draw(
            st.fixed_dictionaries(
                {}, optional={"units": _text, "precision": st.integers(0, 12)}
            )
        )
        return NumberMeta(dtype, display=display, **common), draw(_number_values(dtype))
    if kind == "s":
        return StringMeta(**common), draw(_text)
    if kind == "b":
        return BooleanMeta(**common), draw(st.booleans())
    if kind == "c":
        choices = draw(st.lists(_text, min_size=1, max_size=4, unique=True))
        return ChoiceMeta(choices, **common), draw(st.sampled_from(choices))
    if kind == "na":
        dtype = draw(st.sampled_from(DTYPES))
        value = draw(st.lists(_number_values(dtype), max_size=4))
        return NumberArrayMeta(dtype, **common), value
    if kind == "sa":
        return StringArrayMeta(**common), draw(st.lists(_text, max_size=4))
    if kind == "ba":
        return BooleanArrayMeta(**common), draw(st.lists(st.booleans(), max_size=4))
    if kind == "ca":
        choices = draw(st.lists(_text, min_size=1, max_size=4, unique=True))
        value = draw(st.lists(st.sampled_from(choices), max_size=4))
        return ChoiceArrayMeta(choices, **common), value
    columns = draw(st.lists(_names, min_size=1, max_size=3, unique=True))
    rows = draw(st.integers(0, 3))
    elements, value = {}, {}
    for c in columns:
        meta, _ = draw(metas_and_values(kinds=("na", "sa", "ba", "ca")))
        elements[c] = meta
        element_values = _element_values(meta)
        value[c] = draw(st.lists(element_values, min_size=rows, max_size=rows))
    return TableMeta(elements, **common), value


def _element_values(meta):
    if isinstance(meta, NumberArrayMeta):
        return _number_values(meta.dtype)
    if isinstance(meta, ChoiceArrayMeta):
        return st.sampled_from(meta.choices)
    if isinstance(meta, BooleanArrayMeta):
        return st.booleans()
    return _text


@settings(max_examples=300, deadline=None)
@given(metas_and_values(), _names)
def test_any_attribute_round_trips(meta_value, name):
    meta, value = meta_value
    attr = Attribute(name, meta, value, Alarm.major("m"), TimeStamp(1, 2, 3))
    d = attr.to_dict()
    rebuilt = from_dict(d, name)
    assert rebuilt.to_dict() == d
    assert rebuilt.value == attr.value
    assert from_dict(d["meta"]).to_dict() == meta.to_dict()


@settings(max_examples=50, deadline=None)
@given(
    st.lists(
        st.tuples(_names, metas_and_values()), max_size=5, unique_by=lambda t: t[0]
    )
)
def test_any_block_round_trips(fields):
    block = Block("B", "desc", ["version:x:1"])
    for name, (meta, value) in fields:
        block.add(Attribute(name, meta, value))
    d = block.to_dict()
    assert from_dict(d, "B").to_dict() == d


def test_number_array_meta_carries_display_like_number_meta():
    from malcolm.core import NumberArrayMeta
    from malcolm.core.serialize import from_dict

    meta = NumberArrayMeta("int32", "positions", display={"units": "mm"})
    d = meta.to_dict()
    assert d["display"]["typeid"] == "display_t"
    assert d["display"]["units"] == "mm" and d["display"]["precision"] == 0
    again = from_dict(d)
    assert again.to_dict() == d
    assert again.display["units"] == "mm"

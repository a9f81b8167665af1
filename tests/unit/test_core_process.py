"""Process: finding blocks, and subscriptions that deliver deltas or whole values."""

import asyncio
import logging

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from malcolm.core import (
    Alarm,
    Attribute,
    Block,
    BooleanArrayMeta,
    ChoiceMeta,
    MapMeta,
    Method,
    MethodMeta,
    NotFoundError,
    NumberArrayMeta,
    NumberMeta,
    Process,
    StringMeta,
    TableMeta,
    TimeStamp,
    apply_changes,
)


class FakeController:
    """The least a Process needs: mri, block, start/stop/put/call."""

    def __init__(self, block: Block) -> None:
        self.mri = block.mri
        self.block = block
        self.process = None
        self.started = False

    async def start(self) -> None:
        self.started = True

    async def stop(self) -> None:
        self.started = False

    async def put(self, name, value):
        self.block.attribute(name).set_value(value)

    async def call(self, name, params):
        method = self.block.method(name)
        args = method.meta.validate_args(f"{self.mri}.{name}", params)
        method.set_took(args)
        result = {"doubled": 2 * args["x"]}
        method.set_returned(result, Alarm.ok)
        return result


def _table_meta() -> TableMeta:
    return TableMeta({"x": NumberArrayMeta("int32"), "on": BooleanArrayMeta()})


def make_process() -> tuple[Process, Block]:
    block = Block("B", "test block")
    block.add(Attribute("health", StringMeta(), "OK"))
    block.add(Attribute("n", NumberMeta("int32", writeable=True), 1))
    block.add(Attribute("c", ChoiceMeta(["a", "b"]), "a"))
    block.add(Attribute("t", _table_meta()))
    takes = MapMeta({"x": NumberMeta("int32")}, ["x"])
    block.add(Method("double", MethodMeta(takes, MapMeta({"doubled": NumberMeta()}))))
    process = Process("test")
    process.add_controller(FakeController(block))
    return process, block


class Client:
    """Applies what a delta subscription delivers, as a remote client would."""

    def __init__(self, process: Process, path: list[str], delta: bool = True):
        self.calls: list = []
        self.data = None
        self.delta = delta
        self.sub = process.subscribe(path, self.on_update, delta)

    def on_update(self, payload) -> None:
        self.calls.append(payload)
        self.data = apply_changes(self.data, payload) if self.delta else payload


def current(process: Process, path: list[str]):
    try:
        return process.get(path)
    except NotFoundError:
        return None


# ---- hosting and get


def test_hosting_and_get():
    process, block = make_process()
    assert process.mris == ["B"]
    assert process.get_block("B") is block
    assert process.get(["B"]) == block.to_dict()
    assert process.get(["B", "n", "value"]) == 1
    assert process.get(["B", "meta", "fields"]) == ["health", "n", "c", "t", "double"]
    assert process.get(["B", "n", "meta", "dtype"]) == "int32"
    with pytest.raises(NotFoundError, match="no block 'X' \\(blocks: B\\)"):
        process.get(["X"])
    with pytest.raises(NotFoundError, match="B has no field 'zz'"):
        process.get(["B", "zz"])
    with pytest.raises(NotFoundError, match="no 'value.q'"):
        process.get(["B", "n", "value", "q"])
    with pytest.raises(ValueError, match="already exists"):
        process.add_controller(FakeController(Block("B")))


def test_start_put_post_stop():
    process, block = make_process()

    async def main():
        await process.start()
        assert process.get_controller("B").started
        await process.put(["B", "n", "value"], "7")
        await process.put(["B", "n"], 8.0)
        result = await process.post(["B", "double"], {"x": 4})
        await process.stop()
        return result

    assert asyncio.run(main()) == {"doubled": 8}
    assert block.attribute("n").value == 8
    assert process.get(["B", "double", "took", "value"]) == {"x": 4}
    assert process.get(["B", "double", "returned", "value"]) == {"doubled": 8}
    assert not process.get_controller("B").started


# ---- what changes publish


def test_set_value_publishes_exactly_one_delta():
    process, block = make_process()
    client = Client(process, ["B"])
    block.attribute("n").set_value(5)
    assert len(client.calls) == 2
    changes = client.calls[1]
    assert [c[0] for c in changes] == [["n", "value"], ["n", "timeStamp"]]
    assert changes[0][1] == 5
    block.attribute("n").set_value(6, alarm=Alarm.major("high"))
    assert len(client.calls) == 3
    assert [c[0] for c in client.calls[2]] == [
        ["n", "value"],
        ["n", "alarm"],
        ["n", "timeStamp"],
    ]
    assert client.data == process.get(["B"])


def test_set_value_keeps_given_timestamp():
    process, block = make_process()
    block.attribute("n").set_value(5, timeStamp=TimeStamp(10, 20))
    assert process.get(["B", "n", "timeStamp", "secondsPastEpoch"]) == 10


def test_table_value_delta_matches_get():
    process, block = make_process()
    client = Client(process, ["B"])
    value_client = Client(process, ["B", "t", "value"])
    block.attribute("t").set_value([{"x": 1, "on": True}, {"x": 2}])
    expected = {"x": [1, 2], "on": [True, False], "typeid": "malcolm:core/Table:1.0"}
    assert process.get(["B", "t", "value"]) == expected
    assert value_client.data == expected
    assert client.data == process.get(["B"])


def test_add_and_remove_publish_structure_deltas():
    process, block = make_process()
    client = Client(process, ["B"])
    attr = block.add(Attribute("extra", StringMeta(), "x"))
    fields = ["health", "n", "c", "t", "double", "extra"]
    assert client.calls[-1] == [
        [["extra"], attr.to_dict()],
        [["meta", "fields"], fields],
    ]
    block.remove("extra")
    assert client.calls[-1] == [[["extra"]], [["meta", "fields"], fields[:-1]]]
    assert client.data == process.get(["B"])
    block.remove("nonexistent")  # removing what is not there publishes nothing
    assert len(client.calls) == 3


def test_replacing_a_field_detaches_the_old_one():
    process, block = make_process()
    client = Client(process, ["B", "n"])
    old = block.attribute("n")
    new = block.add(Attribute("n", StringMeta(), "now a string"))
    assert client.calls[-1] == [[[], new.to_dict()]]
    old.set_value(99)  # the replaced attribute no longer publishes
    assert len(client.calls) == 2
    assert client.data == process.get(["B", "n"])
    assert old.block is None and new.block is block


def test_writeable_and_method_logs_publish():
    process, block = make_process()
    client = Client(process, ["B"])
    block.attribute("n").set_writeable(False)
    assert client.calls[-1] == [[["n", "meta", "writeable"], False]]
    block.attribute("n").set_writeable(False)  # no change, no delta
    method = block.method("double")
    method.set_took({"x": 2})
    method.set_returned({"doubled": 4}, Alarm.ok)
    method.set_writeable(False)
    assert len(client.calls) == 5
    assert client.data == process.get(["B"])


# ---- subscription levels


def test_subscribe_at_block_field_and_value_level():
    process, block = make_process()
    whole = Client(process, ["B"])
    fld = Client(process, ["B", "n"])
    value = Client(process, ["B", "n", "value"])
    meta = Client(process, ["B", "meta"])
    assert whole.calls == [[[[], process.get(["B"])]]]
    assert fld.calls == [[[[], process.get(["B", "n"])]]]
    assert value.calls == [[[[], 1]]]
    block.attribute("n").set_value(2)
    assert value.calls[-1] == [[[], 2]]
    assert fld.calls[-1][0] == [["value"], 2]
    assert [c[0] for c in fld.calls[-1]] == [["value"], ["timeStamp"]]
    assert len(meta.calls) == 1  # a value change does not touch the meta
    block.attribute("c").set_value("b")
    assert len(fld.calls) == 2 and len(value.calls) == 2
    assert whole.data == process.get(["B"])
    assert fld.data == process.get(["B", "n"])
    assert value.data == 2


def test_whole_value_subscription():
    process, block = make_process()
    value = Client(process, ["B", "n", "value"], delta=False)
    fld = Client(process, ["B", "n"], delta=False)
    assert value.calls == [1]
    block.attribute("n").set_value(3)
    block.attribute("n").set_alarm(Alarm.major("x"))
    assert value.calls == [1, 3]
    assert fld.calls[-1] == process.get(["B", "n"])
    assert len(fld.calls) == 3


def test_removed_field_gives_delete_then_whole_again():
    process, block = make_process()
    delta = Client(process, ["B", "n", "value"])
    whole = Client(process, ["B", "n", "value"], delta=False)
    block.remove("n")
    assert delta.calls[-1] == [[[]]]
    assert delta.data is None and whole.calls[-1] is None
    block.add(Attribute("n", NumberMeta(), 4.5))
    assert delta.calls[-1] == [[[], 4.5]]
    assert delta.data == 4.5 and whole.calls[-1] == 4.5


def test_subscribe_to_missing_path_fails():
    process, _ = make_process()
    with pytest.raises(NotFoundError):
        process.subscribe(["B", "nope"], print)
    with pytest.raises(NotFoundError):
        process.subscribe([], print)


def test_unsubscribe_stops_delivery():
    process, block = make_process()
    client = Client(process, ["B"])
    process.unsubscribe(client.sub)
    block.attribute("n").set_value(2)
    assert len(client.calls) == 1
    process.unsubscribe(client.sub)  # twice is harmless


def test_raising_subscriber_does_not_break_others(caplog):
    process, block = make_process()

    def bad(payload):
        raise RuntimeError("subscriber bug")

    process.subscribe(["B"], bad)
    client = Client(process, ["B"])
    with caplog.at_level(logging.ERROR):
        block.attribute("n").set_value(2)
    assert client.data == process.get(["B"])
    assert "raised" in caplog.text and "subscriber bug" in caplog.text


def test_unsubscribed_during_delivery_gets_nothing_more():
    process, block = make_process()
    second: list = []

    def first(payload):
        if len(payload) > 1 or payload[0][0]:
            process.unsubscribe(sub2)

    process.subscribe(["B"], first)
    sub2 = process.subscribe(["B"], second.append)
    block.attribute("n").set_value(2)
    assert len(second) == 1


def test_changes_made_by_a_subscriber_arrive_in_order():
    """A callback that changes the block must not reorder others' deltas."""
    process, block = make_process()

    def round_up_to_even(payload):
        for change in payload:
            if change[0] == ["n", "value"] and change[1] % 2:
                block.attribute("n").set_value(change[1] + 1)

    process.subscribe(["B"], round_up_to_even)
    client = Client(process, ["B"])
    values = Client(process, ["B", "n", "value"])
    whole = Client(process, ["B", "n", "value"], delta=False)
    for v in (3, 4, 5):
        block.attribute("n").set_value(v)
    assert block.attribute("n").value == 6
    assert client.data == process.get(["B"])
    assert [c[0][1] for c in values.calls] == [1, 3, 4, 4, 5, 6]
    assert values.data == 6
    assert whole.calls == [1, 3, 4, 4, 5, 6]


def test_subscribe_from_a_callback():
    process, block = make_process()
    late: list[Client] = []

    def subscribe_late(payload):
        if not late:
            late.append(Client(process, ["B", "n"]))

    process.subscribe(["B", "c"], subscribe_late)
    block.attribute("c").set_value("b")
    block.attribute("n").set_value(9)
    assert late[0].data == process.get(["B", "n"])


# ---- property: random changes, every subscriber's data equals get()

NAMES = ["n", "c", "t", "double", "x", "y"]
PATHS = [
    ["B"],
    ["B", "meta"],
    ["B", "meta", "fields"],
    ["B", "n"],
    ["B", "n", "value"],
    ["B", "n", "meta", "writeable"],
    ["B", "c", "value"],
    ["B", "t"],
    ["B", "t", "value"],
    ["B", "double"],
    ["B", "double", "took"],
]


def _new_field(draw, name):
    kind = draw(st.sampled_from(["number", "string", "table", "method"]))
    if kind == "number":
        return Attribute(name, NumberMeta("int32"), draw(st.integers(-5, 5)))
    if kind == "string":
        return Attribute(name, StringMeta(), draw(st.text(max_size=3)))
    if kind == "table":
        return Attribute(name, _table_meta(), draw(_tables))
    return Method(name, MethodMeta(MapMeta({"x": NumberMeta("int32")})))


_tables = st.lists(
    st.fixed_dictionaries({"x": st.integers(-3, 3), "on": st.booleans()}),
    max_size=3,
)


def _values_for(meta):
    if isinstance(meta, TableMeta):
        return _tables
    if isinstance(meta, ChoiceMeta):
        return st.sampled_from(meta.choices)
    if isinstance(meta, NumberMeta):
        return st.integers(-(2**31), 2**31 - 1) if meta.dtype == "int32" else (
            st.floats(allow_nan=False)
        )  # fmt: skip
    return st.text(max_size=3)


def _random_change(draw, block: Block) -> str:
    name = draw(st.sampled_from(NAMES))
    op = draw(
        st.sampled_from(["set", "set", "alarm", "writeable", "add", "remove", "call"])
    )
    if op == "add" or name not in block:
        if name == "health":
            return "skip"
        block.add(_new_field(draw, name))
        return f"add {name}"
    fld = block[name]
    if op == "remove":
        block.remove(name)
        return f"remove {name}"
    if op == "writeable":
        fld.set_writeable(draw(st.booleans()))
        return f"writeable {name}"
    if isinstance(fld, Method):
        fld.set_took({"x": draw(st.integers(0, 3))})
        if draw(st.booleans()):
            fld.set_returned({}, draw(st.sampled_from([Alarm.ok, Alarm.major("e")])))
        return f"call {name}"
    if op == "alarm":
        fld.set_alarm(draw(st.sampled_from([Alarm.ok, Alarm.major("m")])))
        return f"alarm {name}"
    alarm = draw(st.sampled_from([None, Alarm.ok, Alarm.invalid("i")]))
    fld.set_value(draw(_values_for(fld.meta)), alarm=alarm)
    return f"set {name}"


@settings(max_examples=150, deadline=None)
@given(st.data())
def test_deltas_reproduce_get_after_any_changes(data):
    process, block = make_process()
    delta_clients = [Client(process, p) for p in PATHS]
    whole_clients = [Client(process, p, delta=False) for p in PATHS]
    # a subscriber that unsubscribes and one that raises do not disturb the rest
    dropped = Client(process, ["B"])
    process.unsubscribe(dropped.sub)
    process.subscribe(["B"], lambda payload: 1 / 0)
    steps = data.draw(st.integers(1, 25))
    for _ in range(steps):
        data.draw(st.just(_random_change(data.draw, block)))
        for client in delta_clients + whole_clients:
            assert client.data == current(process, client.sub.path), client.sub
    assert len(dropped.calls) == 1

"""Process.subscribe's ``below``: a batch whose changes touching the path all
lie below it, as the block gave them (a pvAccess channel's fast path)."""

import asyncio
from typing import Any

from malcolm.controllers.stateful import StatefulController
from malcolm.core import Process
from malcolm.parts.demo import CounterPart


def make() -> Process:
    process = Process()
    process.add_controller(StatefulController("A", [CounterPart("counter")]))
    return process


def test_changes_below_the_path_come_as_the_block_gave_them():
    async def main() -> None:
        process = make()
        await process.start()
        block = process.get_block("A")
        general: list[Any] = []
        below: list[Any] = []
        whole_general: list[Any] = []
        whole_below: list[Any] = []
        process.subscribe(["A", "counter"], general.append, below=below.append)
        process.subscribe(["A"], whole_general.append, below=whole_below.append)
        assert general[0][0][0] == [] and whole_general[0][0][0] == []  # snapshots
        block.counter.set_value(3.0)
        (changes,) = below
        assert [c[0] for c in changes] == [
            ["counter", "value"],
            ["counter", "timeStamp"],
        ]
        assert changes[0][1] == 3.0
        (whole,) = whole_below
        assert whole is changes or whole == changes  # the block's, not copied
        assert len(general) == 1 and len(whole_general) == 1  # none of it there
        # a change of another field: nothing for the field's subscriber
        block.delta.set_value(2.0)
        assert len(below) == 1 and len(general) == 1
        assert [c[0] for c in whole_below[-1]][0] == ["delta", "value"]
        await process.stop()

    asyncio.run(main())


def test_the_path_itself_or_a_parent_replaced_goes_to_the_callback():
    async def main() -> None:
        process = make()
        await process.start()
        block = process.get_block("A")
        general: list[Any] = []
        below: list[Any] = []
        whole_general: list[Any] = []
        whole_below: list[Any] = []
        process.subscribe(["A", "counter"], general.append, below=below.append)
        process.subscribe(["A"], whole_general.append, below=whole_below.append)
        replaced = block.counter.to_dict()
        # the field replaced whole, with a change below it in the same batch
        block.notify([[["counter"], replaced], [["counter", "value"], 1.0]])
        assert below == [] and general[-1] == [[[], replaced], [["value"], 1.0]]
        assert whole_below[-1][0] == [["counter"], replaced]  # below the block
        # the whole block replaced: relative to each path, to the callback
        block.notify([[[], process.get(["A"])]])
        assert below == [] and general[-1][0][0] == []
        assert whole_general[-1][0][0] == [] and len(whole_below) == 1
        await process.stop()

    asyncio.run(main())


def test_deliveries_keep_their_order_across_both_callbacks():
    """A change made by a subscriber while a batch is delivered comes after
    that batch to every subscriber, whichever of its callbacks gets it."""

    async def main() -> None:
        process = make()
        await process.start()
        block = process.get_block("A")
        seen: list[tuple[str, float]] = []

        def first(changes: list[Any]) -> None:
            value = changes[0][1]
            seen.append(("first", value))
            if value == 1.0:
                block.counter.set_value(2.0)  # nested

        def second(changes: list[Any]) -> None:
            seen.append(("second", changes[0][1]))

        process.subscribe(["A", "counter"], lambda _: None, below=first)
        process.subscribe(["A", "counter"], lambda _: None, below=second)
        block.counter.set_value(1.0)
        assert seen == [
            ("first", 1.0),
            ("second", 1.0),
            ("first", 2.0),
            ("second", 2.0),
        ]
        await process.stop()

    asyncio.run(main())


def test_below_is_ignored_for_whole_values():
    async def main() -> None:
        process = make()
        await process.start()
        values: list[Any] = []
        below: list[Any] = []
        process.subscribe(["A", "counter"], values.append, False, below=below.append)
        process.get_block("A").counter.set_value(4.0)
        assert below == [] and values[-1]["value"] == 4.0
        await process.stop()

    asyncio.run(main())


def test_a_field_subscriber_gets_what_below_would_give_for_every_batch_shape():
    """_on_changes tests a field's and a block's subscribers in line: for
    batches all below the field, mixed with other fields', of other fields
    only, and replacing the field or the block, it delivers what _below says
    (or the callback)."""
    from malcolm.core.process import _below

    async def main() -> None:
        process = make()
        await process.start()
        got: list[tuple[str, Any]] = []
        whole: list[tuple[str, Any]] = []
        process.subscribe(
            ["A", "counter"],
            lambda p: got.append(("callback", p)),
            below=lambda p: got.append(("below", p)),
        )
        process.subscribe(
            ["A"],
            lambda p: whole.append(("callback", p)),
            below=lambda p: whole.append(("below", p)),
        )
        got.clear()
        value = ["counter", "value"]
        stamp = ["counter", "timeStamp"]
        other = ["delta", "value"]
        batches = [
            [[value, 1.0], [stamp, 2]],
            [[other, 1.0], [value, 2.0]],
            [[value, 2.0], [other, 1.0], [stamp, 3]],
            [[other, 4.0]],
            [[["counter"], process.get(["A", "counter"])]],
            [[value, 5.0], [["counter"]]],
        ]
        whole.clear()
        process._on_changes("A", [[value, 6.0], [[], process.get(["A"])]])
        assert [kind for kind, _ in whole] == ["callback"]  # the block replaced
        for changes in batches:
            got.clear()
            whole.clear()
            process._on_changes("A", changes)
            assert whole == [("below", changes)] and whole[0][1] is changes
            expected = _below(["counter"], changes)
            if expected is None:
                assert [kind for kind, _ in got] == ["callback"], changes
            elif expected:
                assert got == [("below", expected)], changes
                if expected == changes:
                    assert got[0][1] is changes  # as the block gave them
            else:
                assert got == [], changes

    asyncio.run(main())

"""Process.remove_controller: a block that stops being hosted at run time."""

import asyncio

import pytest

from malcolm.controllers.stateful import StatefulController
from malcolm.core import NotFoundError, Process
from malcolm.parts.demo import CounterPart


def test_removed_block_is_gone_and_its_subscribers_told():
    async def main():
        process = Process()
        process.add_controller(StatefulController("A", [CounterPart("counter")]))
        process.add_controller(StatefulController("B", [CounterPart("counter")]))
        await process.start()
        deltas, values, others = [], [], []
        process.subscribe(["A", "counter"], deltas.append)
        process.subscribe(["A", "counter", "value"], values.append, delta=False)
        process.subscribe(["B", "counter", "value"], others.append, delta=False)
        controller = process.get_controller("A")
        await controller.stop()
        assert process.remove_controller("A") is controller
        assert process.mris == ["B"]
        with pytest.raises(NotFoundError):
            process.get(["A"])
        assert deltas[-1] == [[[]]] and values[-1] is None
        n = len(deltas)
        controller.block.counter.set_value(5.0)  # no longer delivered
        assert len(deltas) == n
        await process.put(["B", "counter"], 2)
        assert others[-1] == 2.0
        await process.stop()

    asyncio.run(main())

"""The simulated IOC's status records posted at a bounded rate
(malcolm.sim.beamline_ioc.status.Throttled), on a real asyncio loop."""

from __future__ import annotations

import asyncio
from typing import Any

from malcolm.sim.beamline_ioc.pace import STATUS_PERIOD, Throttled


class Record:
    """What Throttled uses of a softioc input record: get, and set (a post)."""

    def __init__(self, value: Any = 0) -> None:
        self.value = value
        self.posts: list[tuple[Any, dict[str, Any]]] = []

    def get(self) -> Any:
        return self.value

    def set(self, value: Any, **fields: Any) -> None:
        self.value = value
        self.posts.append((value, fields))


def posted(record: Record) -> list[Any]:
    return [value for value, _ in record.posts]


def test_a_burst_is_posted_at_once_then_the_latest_at_the_period_end():
    async def scenario():
        record = Record()
        status = Throttled(record)
        for n in range(1, 1001):  # no await: all within one period
            status.set(n)
            assert status.get() == n  # the IOC reads what it set
        assert posted(record) == [1]  # the first at once
        await asyncio.sleep(3 * STATUS_PERIOD)
        assert posted(record) == [1, 1000]  # one more, the latest value
        await asyncio.sleep(3 * STATUS_PERIOD)
        assert posted(record) == [1, 1000]  # nothing left pending

    asyncio.run(scenario())


def test_changes_slower_than_the_period_are_each_posted():
    async def scenario():
        record = Record()
        status = Throttled(record)
        for n in range(1, 5):
            status.set(n)
            await asyncio.sleep(2 * STATUS_PERIOD)
        assert posted(record) == [1, 2, 3, 4]

    asyncio.run(scenario())


def test_flush_posts_the_latest_now_and_cancels_the_pending_post():
    async def scenario():
        record = Record(7)
        status = Throttled(record)
        status.flush()
        assert posted(record) == []  # nothing new: nothing posted
        status.set(1)
        status.set(2)
        status.set(3)
        status.flush()
        assert posted(record) == [1, 3]
        await asyncio.sleep(3 * STATUS_PERIOD)
        assert posted(record) == [1, 3]  # the pending post went with the flush
        status.flush(severity=2, alarm=7)  # with fields: posted anyway
        assert record.posts[-1] == (3, {"severity": 2, "alarm": 7})

    asyncio.run(scenario())


def test_outside_a_loop_every_set_is_posted():
    record = Record()
    status = Throttled(record)
    status.set(1)
    status.set(2)
    assert posted(record) == [1, 2]

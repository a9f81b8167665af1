"""A call's took and returned: one batch when the method does not wait
(``Process.hold``), the took first and never after anything its method
published; a method that waits has its took published before it waits."""

from __future__ import annotations

import asyncio
from typing import Any

import pytest

from malcolm.controllers.base import Controller
from malcolm.core import Alarm, NumberMeta, Process
from malcolm.parts import Part


class Calls(Part):
    """Methods that do not wait, wait, change an attribute, raise."""

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.go = asyncio.Event()

    def setup(self, registrar) -> None:
        self.level = registrar.add_attribute("level", NumberMeta(), 0.0)
        self.cancelled = False
        for func in (
            self.quick,
            self.slow,
            self.touch,
            self.fail,
            self.other,
            self.maybe,
            self.afail,
        ):
            registrar.add_method(func)

    def quick(self, x: float = 1.0) -> None:
        """Return at once."""

    async def slow(self) -> dict[str, Any]:
        """Wait for go."""
        try:
            await self.go.wait()
        except asyncio.CancelledError:
            self.cancelled = True
            raise
        return {}

    async def maybe(self, wait: float = 0.0) -> None:
        """Wait only if told to (an async method that may not wait)."""
        if wait:
            await asyncio.sleep(wait)

    async def afail(self) -> None:
        """Raise before waiting."""
        raise ValueError("bad y")

    def touch(self, x: float = 2.0) -> None:
        """Set the level, then return."""
        self.level.set_value(x)

    def fail(self) -> None:
        """Raise."""
        raise ValueError("bad x")

    def other(self) -> None:
        """Change another block."""
        self.elsewhere.level.set_value(5.0)


async def _two() -> tuple[Controller, Controller, list[Any]]:
    process = Process("test")
    a, b = Controller("A", [Calls("p")]), Controller("B", [Calls("p")])
    process.add_controller(a)
    process.add_controller(b)
    a.parts["p"].elsewhere = b.block
    await process.start()
    seen: list[Any] = []
    for mri in ("A", "B"):
        process.subscribe([mri], lambda changes, m=mri: seen.append((m, changes)))
    seen.clear()  # the first, whole, values
    return a, b, seen


def _paths(seen: list[Any]) -> list[tuple[str, list[tuple[str, ...]]]]:
    return [(mri, [tuple(c[0][:2]) for c in changes]) for mri, changes in seen]


def test_a_call_that_does_not_wait_publishes_took_and_returned_as_one_batch():
    async def main() -> None:
        a, _, seen = await _two()
        await a.call("quick", {})
        assert _paths(seen) == [("A", [("quick", "took"), ("quick", "returned")])]
        ((_, [took, returned]),) = seen
        assert took[1] == a.block.quick.took.to_dict()
        assert returned[1] == a.block.quick.returned.to_dict()
        seen.clear()
        with pytest.raises(ValueError, match="bad x"):
            await a.call("fail", {})
        assert _paths(seen) == [("A", [("fail", "took"), ("fail", "returned")])]
        assert seen[0][1][1][1]["alarm"]["severity"] == Alarm.major("x").severity

    asyncio.run(main())


def test_what_a_method_publishes_comes_after_its_took():
    async def main() -> None:
        a, b, seen = await _two()
        await a.call("touch", {})
        assert _paths(seen) == [
            ("A", [("touch", "took")]),
            ("A", [("level", "value"), ("level", "timeStamp")]),
            ("A", [("touch", "returned")]),
        ]
        seen.clear()
        await a.call("other", {})
        assert _paths(seen) == [
            ("A", [("other", "took")]),
            ("B", [("level", "value"), ("level", "timeStamp")]),
            ("A", [("other", "returned")]),
        ]

    asyncio.run(main())


def test_a_method_that_waits_has_its_took_published_before_it_waits():
    async def main() -> None:
        a, _, seen = await _two()
        call = asyncio.ensure_future(a.call("slow", {}))
        await asyncio.sleep(0.01)
        assert _paths(seen) == [("A", [("slow", "took")])]
        await a.call("quick", {})  # another call meanwhile: its own batch
        assert _paths(seen)[1:] == [("A", [("quick", "took"), ("quick", "returned")])]
        a.parts["p"].go.set()
        await call
        assert _paths(seen)[2:] == [("A", [("slow", "returned")])]
        assert a.process is not None and a.process._held is None

    asyncio.run(main())


def test_a_held_change_is_released_by_hand_and_by_another_hold():
    async def main() -> None:
        a, _, seen = await _two()
        process = a.process
        assert process is not None
        process.hold("A", [["quick", "took"], {"x": 1}], ["quick", "returned"])
        assert seen == []
        process.release()
        assert _paths(seen) == [("A", [("quick", "took")])]
        process.release()  # nothing held: nothing published
        process.hold("A", [["quick", "took"], {"x": 2}], ["quick", "returned"])
        process.hold("B", [["quick", "took"], {"x": 3}], ["quick", "returned"])
        assert _paths(seen)[1:] == [("A", [("quick", "took")])]
        process.release()
        assert _paths(seen)[2:] == [("B", [("quick", "took")])]

    asyncio.run(main())


def test_an_async_method_that_does_not_wait_is_one_batch_too():
    async def main() -> None:
        a, _, seen = await _two()
        await a.call("maybe", {})
        assert _paths(seen) == [("A", [("maybe", "took"), ("maybe", "returned")])]
        seen.clear()
        with pytest.raises(ValueError, match="bad y"):
            await a.call("afail", {})
        assert _paths(seen) == [("A", [("afail", "took"), ("afail", "returned")])]
        seen.clear()
        await a.call("maybe", {"wait": 0.001})  # waits: two batches
        assert _paths(seen) == [
            ("A", [("maybe", "took")]),
            ("A", [("maybe", "returned")]),
        ]

    asyncio.run(main())


def test_a_method_cancelled_while_it_waits_is_cancelled_inside():
    async def main() -> None:
        a, _, seen = await _two()
        call = asyncio.ensure_future(a.call("slow", {}))
        await asyncio.sleep(0.01)
        assert _paths(seen) == [("A", [("slow", "took")])]
        call.cancel()
        with pytest.raises(asyncio.CancelledError):
            await call
        assert a.parts["p"].cancelled
        assert _paths(seen) == [("A", [("slow", "took")])]  # no returned

    asyncio.run(main())


def test_a_batch_of_took_and_returned_reaches_each_kind_of_subscriber():
    """The one batch of a call that does not wait goes to a ``below``
    subscriber of its method (as the block gave it: its logs as MethodLogs)
    and of its block, not to one of another field; a subscriber of a path
    below the method, or a plain callback, gets it relative and plain."""

    async def main() -> None:
        a, _, _ = await _two()
        process = a.process
        assert process is not None
        got: dict[str, list[Any]] = {}

        def sub(path: list[str], below: bool) -> None:
            name = ".".join(path) + (" below" if below else "")
            seen = got.setdefault(name, [])
            callback = seen.append
            process.subscribe(path, callback, below=callback if below else None)
            seen.clear()

        for path in (["A", "quick"], ["A", "level"], ["A"]):
            sub(path, True)
        sub(["A", "quick"], False)
        sub(["A", "quick", "took"], False)
        await a.call("quick", {"x": 3.0})
        method = a.block.quick
        ((took, returned),) = got["A.quick below"]
        assert took == [["quick", "took"], method.took]
        assert returned == [["quick", "returned"], method.returned]
        assert got["A below"] == got["A.quick below"]
        assert got["A.level below"] == []
        assert got["A.quick"] == [
            [
                [["took"], method.took.to_dict()],
                [["returned"], method.returned.to_dict()],
            ]
        ]
        assert got["A.quick.took"] == [[[[], method.took.to_dict()]]]
        assert method.took.value == {"x": 3.0}

    asyncio.run(main())

"""The served call and put paths of Controller keep their semantics while
doing less per operation: the origins of puts in flight, the put handler
chosen, state checks, argument validation and the took/returned logs."""

from __future__ import annotations

import asyncio
from types import MappingProxyType
from typing import Any

import pytest

from malcolm.controllers.base import Controller
from malcolm.controllers.writers import PutsInFlight
from malcolm.core import (
    Alarm,
    BadValueError,
    MapMeta,
    NotAllowedError,
    NumberMeta,
    OffLoopError,
    Process,
    StringMeta,
    TimeStamp,
)
from malcolm.core.fields import MethodLog
from malcolm.core.threads import guard_trips
from malcolm.embed import start_process
from malcolm.hooks.origin import writing_as
from malcolm.parts import Part


def test_puts_in_flight_latest_writer_and_out_of_order_ends():
    puts = PutsInFlight()
    with writing_as("A"):
        a = puts.begin("x")
    with writing_as("B"):
        b = puts.begin("x")
    assert puts.writer_of("x") == "B"
    puts.end("x", a)  # the earlier put ends first: B is still writing
    assert puts.writer_of("x") == "B"
    puts.end("x", b)
    assert puts.writer_of("x") is None
    assert puts._origins == {}
    c = puts.begin("y")  # nobody: None, and forgotten at its end
    assert puts.writer_of("y") is None and puts._origins == {"y": [c]}
    puts.end("y", c)
    puts.end("y", c)  # a second end changes nothing
    assert puts._origins == {}


def test_puts_in_flight_context_manager_still_works():
    puts = PutsInFlight()
    with writing_as("M"), puts.put("x"):
        assert puts.writer_of("x") == "M"
    assert puts.writer_of("x") is None


class Slow(Part):
    """A writeable ``slow`` attribute whose put waits for ``release``, and
    a ``bad`` one whose put raises; ``greet`` and ``fail`` methods."""

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.release = asyncio.Event()
        self.seen: list[str | None] = []

    def setup(self, registrar) -> None:
        self.slow = registrar.add_attribute(
            "slow", NumberMeta("int32", writeable=True), 0
        )
        self.slow.put_handler = self.put_slow
        self.bad = registrar.add_attribute("bad", NumberMeta(writeable=True), 0.0)
        self.bad.put_handler = self.put_bad
        registrar.add_method(
            self.greet,
            returns=MapMeta({"greeting": StringMeta("The greeting")}, ["greeting"]),
        )
        registrar.add_method(self.fail)

    async def put_slow(self, value: int) -> None:
        await self.release.wait()
        self.slow.set_value(value)

    def put_bad(self, value: float) -> None:
        raise RuntimeError("no")

    async def greet(self, name: str, times: int = 1) -> dict[str, str]:
        """Greet name, times times."""
        return {"greeting": " ".join([f"Hello {name}"] * times)}

    def fail(self) -> None:
        """Raise."""
        raise RuntimeError("failed on purpose")


async def _controller(part: Part, cls: type[Controller] = Controller) -> Controller:
    controller = cls("T", [part])
    process = Process("test")
    process.add_controller(controller)
    await process.start()
    return controller


def test_put_records_its_writer_until_the_handler_ends_even_if_it_raises():
    async def main() -> None:
        part = Slow("p")
        c = await _controller(part)
        with writing_as("MGR"):
            put = asyncio.ensure_future(c.put("slow", "7"))
        await asyncio.sleep(0)
        assert c.writer_of("slow") == "MGR"
        part.release.set()
        await put
        assert c.writer_of("slow") is None and c.block.slow.value == 7
        with pytest.raises(RuntimeError, match="no"):
            await c.put("bad", 1.0)
        assert c.writer_of("bad") is None
        assert c.puts_in_flight._origins == {}
        with pytest.raises(BadValueError, match=r"^T\.slow: "):
            await c.put("slow", "x")
        assert c.block.slow.value == 7

    asyncio.run(main())


def test_a_controllers_own_put_method_wins_and_is_looked_up_once():
    class Own(Controller):
        calls: list[int] = []

        def put_slow(self, value: int) -> None:
            self.calls.append(value)

    async def main() -> None:
        part = Slow("p")
        c = await _controller(part, Own)
        await c.put("slow", 3)
        await c.put("slow", 4)
        assert Own.calls == [3, 4] and c.block.slow.value == 0
        assert c._put_methods["slow"] == c.put_slow
        part.release.set()
        with pytest.raises(RuntimeError):
            await c.put("bad", 2.0)  # no put_bad: the part's handler
        assert c._put_methods["bad"] is None

    asyncio.run(main())


def test_call_validates_checks_state_and_logs_took_and_returned():
    async def main() -> None:
        c = await _controller(Slow("p"))
        result = await c.call("greet", {"name": "me", "times": "2"})
        assert result == {"greeting": "Hello me Hello me"}
        greet = c.block.greet
        assert greet.took.value == {"name": "me", "times": 2}
        assert greet.took.present == ["name", "times"]
        assert greet.returned.value == result and greet.returned.present == ["greeting"]
        assert greet.returned.timeStamp.to_time() >= greet.took.timeStamp.to_time()
        assert greet.took.timeStamp.secondsPastEpoch > 0
        await c.call("greet", {"name": "you"})  # the default, validated
        assert greet.took.value == {"name": "you", "times": 1}
        with pytest.raises(BadValueError, match=r"^T\.greet\.times: expected"):
            await c.call("greet", {"name": "me", "times": "x"})
        with pytest.raises(BadValueError, match=r"^T\.greet\.name: missing required"):
            await c.call("greet", {})
        with pytest.raises(BadValueError, match=r"^T\.greet\.who: unknown argument"):
            await c.call("greet", {"name": "me", "who": 1})
        with pytest.raises(BadValueError, match="arguments must be a mapping"):
            await c.call("greet", ["me"])  # type: ignore[arg-type]
        assert greet.took.value == {"name": "you", "times": 1}  # refusals: no log
        with pytest.raises(RuntimeError, match="failed on purpose"):
            await c.call("fail")
        fail = c.block.fail
        assert fail.returned.alarm.severity == 2
        assert "failed on purpose" in fail.returned.alarm.message
        await c.call("disable")
        with pytest.raises(NotAllowedError, match=r"T: reset\(\)|T: disable\(\)"):
            await c.call("disable")
        assert c.block.disable.took.value == {}

    asyncio.run(main())


def test_the_logs_delivered_are_the_logs_kept_and_not_shared():
    class Returns(Part):
        def setup(self, registrar) -> None:
            registrar.add_method(self.view, returns=MapMeta({"a": NumberMeta()}, ["a"]))

        def view(self, a: float = 1.5) -> Any:
            """Return a mapping that is not a dict."""
            return MappingProxyType({"a": a})

    async def main() -> None:
        c = await _controller(Returns("r"))
        seen: list[Any] = []
        c.process.subscribe(["T", "view"], seen.append)
        result = await c.call("view", {})
        assert dict(result) == {"a": 1.5}
        method = c.block.view
        assert method.returned.value == {"a": 1.5}
        # a method that does not wait: took and returned in one batch
        assert len(seen) == 2
        took, returned = seen[1]
        assert took == [["took"], method.took.to_dict()]
        assert returned == [["returned"], method.returned.to_dict()]
        assert returned[1]["alarm"] == Alarm.ok.to_dict()
        assert returned[1]["value"] is not method.returned.value
        returned[1]["alarm"]["message"] = "changed by a subscriber"
        assert method.returned.to_dict()["alarm"] == Alarm.ok.to_dict()
        assert method.took.to_dict()["alarm"]["message"] == ""
        log = MethodLog({"x": [1]}, ["x"], Alarm.major("m"), TimeStamp(4, 5))
        assert log.to_dict() == {
            "typeid": "malcolm:core/MethodLog:1.0",
            "value": {"x": [1]},
            "present": ["x"],
            "alarm": Alarm.major("m").to_dict(),
            "timeStamp": TimeStamp(4, 5).to_dict(),
        }

    asyncio.run(main())


def test_a_change_delivers_the_value_and_stamp_the_attribute_keeps():
    async def main() -> None:
        part = Slow("p")
        c = await _controller(part)
        seen: list[Any] = []
        c.process.subscribe(["T", "slow"], seen.append)
        part.slow.set_value(5)
        value, stamp = seen[-1]
        assert value == [["value"], 5]
        assert stamp == [["timeStamp"], part.slow.timeStamp.to_dict()]
        assert part.slow.timeStamp.secondsPastEpoch > 0
        part.slow.set_value(6, timeStamp=TimeStamp(7, 8))
        assert seen[-1][-1] == [["timeStamp"], TimeStamp(7, 8).to_dict()]
        assert part.slow.timeStamp == TimeStamp(7, 8)
        part.slow.set_value(9, alarm=Alarm.minor("low"))
        assert [c[0] for c in seen[-1]] == [["value"], ["alarm"], ["timeStamp"]]
        assert c.process.get(["T", "slow"])["timeStamp"] == seen[-1][-1][1]

    asyncio.run(main())


def test_the_loop_guard_still_refuses_logs_and_values_from_another_thread():
    process = Process("guarded")
    process.add_controller(Controller("T", [Slow("p")]))
    tp = start_process(process, timeout=10)
    try:
        block = process.get_block("T")
        with pytest.raises(OffLoopError, match=r"T\.greet"):
            block.greet.set_took({"name": "x"})
        with pytest.raises(OffLoopError, match=r"T\.greet"):
            block.greet.set_returned({"greeting": "x"}, Alarm.ok)
        with pytest.raises(OffLoopError, match=r"T\.slow"):
            block.slow.set_value(3)
        assert block.greet.took.value == {} and block.greet.returned.value == {}
        assert block.slow.value == 0
    finally:
        guard_trips.clear()  # tripped on purpose
        tp.stop(timeout=10)

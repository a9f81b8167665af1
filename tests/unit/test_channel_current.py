"""Channel.current and ca.Action: an action that waits on a PV the block
also shows returns only once the block shows what the action judged.

The soft backend's ``hold_monitors`` is a monitor that lags a get's answer,
as Channel Access monitors may: a get reads the new value while the events
that bring it to the subscribers are still on their way."""

import asyncio

import pytest

from malcolm.controllers.stateful import StatefulController
from malcolm.core import Process
from malcolm.io import ChannelTimeoutError, DisconnectedError, SoftBackend, use_backend
from malcolm.parts.ca import CAActionPart
from malcolm.parts.soft import CABoolPart

from .scans import run


def motor_process(backend: SoftBackend) -> Process:
    process = Process("ca")
    parts = [
        CABoolPart("doneMoving", rbv="M:DMOV"),
        CAActionPart(
            "stop",
            pv="M:STOP",
            status_pv="M:DMOV",
            good_status="1",
            bad_status=None,
            timeout=5,
        ),
    ]
    process.add_controller(StatefulController("M", parts))
    use_backend(process, "ca", backend)
    return process


def test_an_action_returns_once_the_blocks_attribute_shows_its_status():
    backend = SoftBackend()
    backend.define("M:DMOV", 0)
    backend.define("M:STOP", 0)

    async def scenario():
        process = motor_process(backend)
        await process.start()
        block = process.get_block("M")
        assert block.doneMoving.value is False
        backend.hold_monitors("M:DMOV")  # the event lags: a get reads 1 first
        backend.set("M:DMOV", 1)
        asyncio.get_running_loop().call_later(0.05, backend.release_monitors, "M:DMOV")
        await process.post(["M", "stop"])
        shown = block.doneMoving.value  # right as stop returns
        await process.stop()
        return shown

    assert run(scenario) is True
    assert backend.records["M:STOP"].puts == 1


def test_current_waits_for_the_subscription_to_bring_what_a_get_read():
    backend = SoftBackend()
    backend.define("X", 0)

    async def scenario():
        channel = backend.channel("X")
        seen = []
        channel.subscribe(lambda reading: seen.append(reading.value))
        await channel.connect(1)
        assert (await channel.current(1)).value == 0  # caught up already
        backend.hold_monitors("X")
        backend.set("X", 1)
        waiting = asyncio.ensure_future(channel.current(5))
        await asyncio.sleep(0.01)
        assert not waiting.done() and seen == [0]
        backend.set("X", 2)  # the monitor brings 2 only: a later timeStamp
        backend.release_monitors("X")
        reading = await waiting
        assert reading.value == 2 and channel.latest == reading
        await backend.close()
        return seen

    assert run(scenario) == [0, 2]


def test_current_times_out_or_fails_naming_the_channel():
    backend = SoftBackend()
    backend.define("X", 0)

    async def scenario():
        channel = backend.channel("X")
        await channel.connect(1)
        backend.hold_monitors("X")
        backend.set("X", 1)
        with pytest.raises(ChannelTimeoutError, match=r"X: no monitor event brought 1"):
            await channel.current(0.02)
        waiting = asyncio.ensure_future(channel.current(5))
        await asyncio.sleep(0.01)
        backend.drop("X", "connection lost")
        with pytest.raises(DisconnectedError, match="X: connection lost"):
            await waiting
        assert channel.latest is None
        await backend.close()

    run(scenario)


def test_same_value_compares_arrays_and_nan():
    import numpy as np

    from malcolm.io.channel import same_value

    assert same_value(np.array([1.0, np.nan]), np.array([1.0, np.nan]))
    assert not same_value(np.array([1.0, 2.0]), np.array([1.0, 3.0]))
    assert not same_value(np.array([1.0]), np.array([1.0, 1.0]))
    assert same_value(float("nan"), float("nan")) and same_value("a", "a")
    assert not same_value(1, 2)

"""The channel protocol on the soft backend: connect (with its timeout),
get, put with completion (and its timeout), subscribe, connection changes,
close, and callbacks from other threads reaching the loop."""

import asyncio
import threading

import pytest

from malcolm.core import Alarm
from malcolm.io import (
    ChannelClosedError,
    ChannelError,
    ChannelInfo,
    ChannelTimeoutError,
    ConnectionState,
    DisconnectedError,
    SoftBackend,
)

from .scans import run

SHORT = 0.05


def test_connect_get_and_the_info_a_backend_reports():
    async def scenario():
        backend = SoftBackend()
        backend.define(
            "M:RBV", 1.5, limits=(0, 10), units="mm", precision=3, choices=None
        )
        channel = backend.channel("M:RBV", "M")
        assert channel.state is ConnectionState.IDLE
        info = await channel.connect(timeout=1)
        assert channel.state is ConnectionState.CONNECTED and channel.message == ""
        reading = await channel.get()
        return info, reading, channel.name

    info, reading, name = run(scenario)
    assert info == ChannelInfo(limits=(0, 10), units="mm", precision=3)
    assert (reading.value, reading.alarm) == (1.5, Alarm.ok)
    assert name == "M (readback M:RBV)"


def test_a_connect_that_times_out_goes_on_trying():
    async def scenario():
        backend = SoftBackend()
        backend.drop("P", "IOC down")
        channel = backend.channel("P", default=0)
        changes, readings = [], []
        channel.watch_connection(lambda s, m: changes.append((s, m)))
        channel.subscribe(readings.append)
        with pytest.raises(ChannelTimeoutError, match=r"P: not connected within .*"):
            await channel.connect(timeout=SHORT)
        assert channel.state is ConnectionState.CONNECTING
        assert channel.message == "P: IOC down"
        with pytest.raises(DisconnectedError, match="P: P: IOC down"):
            await channel.get()
        backend.restore("P")  # no second connect() needed
        return changes, [r.value for r in readings], channel.state

    changes, values, state = run(scenario)
    assert state is ConnectionState.CONNECTED
    assert changes == [(ConnectionState.CONNECTED, "")]
    assert values == [0]


def test_put_waits_for_completion_and_its_timeout_does_not_cancel_it():
    async def scenario():
        backend = SoftBackend()
        channel = backend.channel("P:RBV", "P", default=0.0)
        await channel.connect()
        backend.hold_puts("P")
        with pytest.raises(ChannelTimeoutError, match="not complete .* it goes on"):
            await channel.put(1.0, timeout=SHORT)
        waiting = asyncio.ensure_future(channel.put(2.0))
        for _ in range(3):  # until it waits behind the first
            await asyncio.sleep(0)
        assert not waiting.done() and backend.records["P"].puts == 0
        backend.release_puts("P")
        await waiting
        return backend.records, (await channel.get()).value

    records, readback = run(scenario)
    assert records["P"].puts == 2  # the put that timed out completed too
    assert readback == 2.0 and records["P:RBV"].value == 2.0


def test_a_readback_follows_its_demand():
    async def scenario():
        backend = SoftBackend()
        backend.define("E:RBV", 0.0, follow=lambda demand: round(demand, 1))
        channel = backend.channel("E:RBV", "E")
        await channel.connect()
        await channel.put(0.123)
        return backend.records["E"].value, (await channel.get()).value

    assert run(scenario) == (0.123, 0.1)


def test_subscribers_get_every_change_until_they_unsubscribe():
    async def scenario():
        backend = SoftBackend()
        channel = backend.channel("T", default=0)
        readings = []
        end = channel.subscribe(readings.append)
        await channel.connect()
        backend.set("T", 5, Alarm.minor("high"))
        end()
        backend.set("T", 6)
        return [(r.value, r.alarm) for r in readings]

    assert run(scenario) == [(0, Alarm.ok), (5, Alarm.minor("high"))]


def test_a_lost_connection_is_told_and_refuses_gets_and_puts():
    async def scenario():
        backend = SoftBackend()
        channel = backend.channel("Q:RBV", "Q", default=1)
        changes = []
        channel.watch_connection(lambda s, m: changes.append((s, m)))
        await channel.connect()
        backend.drop("Q")
        with pytest.raises(DisconnectedError, match=r"Q \(readback Q:RBV\)"):
            await channel.put(2)
        with pytest.raises(DisconnectedError, match="Q: connection lost"):
            await channel.get()
        backend.restore("Q")
        await channel.put(3)
        return changes, backend.records["Q:RBV"].value

    changes, value = run(scenario)
    assert changes == [
        (ConnectionState.CONNECTED, ""),
        (ConnectionState.DISCONNECTED, "Q: connection lost"),
        (ConnectionState.CONNECTED, ""),
    ]
    assert value == 3


def test_a_readback_only_channel_cannot_be_put_to():
    async def scenario():
        channel = SoftBackend().channel("R")
        await channel.connect()
        with pytest.raises(ChannelError, match="R is a readback: it has no PV"):
            await channel.put(1)

    run(scenario)


def test_close_ends_everything():
    async def scenario():
        backend = SoftBackend()
        channel = backend.channel("C", default=0)
        readings = []
        channel.subscribe(readings.append)
        await channel.connect()
        await backend.close()
        assert channel.state is ConnectionState.CLOSED
        backend.set("C", 1)
        for call in (channel.get(), channel.connect(), channel.put(1)):
            with pytest.raises(ChannelError, match="C"):
                await call
        with pytest.raises(ChannelClosedError):
            channel.subscribe(print)
        return len(readings)

    assert run(scenario) == 1


def test_callbacks_from_a_library_thread_run_on_the_loop():
    async def scenario():
        backend = SoftBackend()
        channel = backend.channel("L", default=0)
        seen = asyncio.Event()
        threads = []

        def on_reading(reading):
            threads.append((reading.value, threading.current_thread()))
            if reading.value == 9:
                seen.set()

        channel.subscribe(on_reading)
        await channel.connect()
        # a library's own thread reports a new value
        library = threading.Thread(target=backend.set, args=("L", 9))
        library.start()
        await seen.wait()
        library.join()
        return threads, threading.current_thread()

    threads, loop_thread = run(scenario)
    assert [v for v, _ in threads] == [0, 9]
    assert all(t is loop_thread for _, t in threads)

"""The ``pva`` channel backend as a channel of the protocol (docs/channels.md)
on fields of a served demo process: connect, info, get, put, subscribe,
a lost connection, and that a process picks it for transport ``pva``."""

from __future__ import annotations

import asyncio

import pytest

from malcolm.core import Process
from malcolm.io import ConnectionState, DisconnectedError, backend_for

from .test_client_cli import free_port, serve_demo, stop
from .test_client_two_process import wait_for


def test_a_field_of_a_served_block_as_a_channel():
    from malcolm.io.pva.client_backend import PvaBackend

    port = free_port()
    a = serve_demo(port)

    async def main():
        nonlocal a
        process = Process("b")
        backend = backend_for(process, "pva")
        assert isinstance(backend, PvaBackend)
        backend = backend.for_address(f"127.0.0.1:{port}")
        channel = backend.channel("MOTOR:X.velocity", "MOTOR:X.velocity")
        readings, states = [], []
        channel.subscribe(readings.append)
        channel.watch_connection(lambda state, message: states.append(state))
        info = await channel.connect(timeout=10)
        assert info.writeable is True
        assert readings[-1].value == 100.0
        await channel.put(12.5)
        assert (await channel.get()).value == 12.5
        await wait_for(lambda: readings[-1].value == 12.5, "monitor 12.5", 10)
        stop(a)
        await wait_for(
            lambda: channel.state is ConnectionState.DISCONNECTED, "lost", 10
        )
        with pytest.raises(DisconnectedError, match="MOTOR:X.velocity"):
            await channel.put(1.0)
        a = serve_demo(port)
        await wait_for(lambda: channel.state is ConnectionState.CONNECTED, "back", 40)
        assert readings[-1].value == 100.0  # a new process, its own value
        assert states == [
            ConnectionState.CONNECTED,
            ConnectionState.DISCONNECTED,
            ConnectionState.CONNECTED,
        ]
        await process.stop()  # closes the backend and its channels
        assert channel.state is ConnectionState.CLOSED

    try:
        asyncio.run(main())
    finally:
        stop(a)

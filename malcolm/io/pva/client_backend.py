"""The ``pva`` channel backend: pvAccess channels on p4p client contexts.

``register_backend("pva", "p4p", PvaBackend, default=True)``: a process's
``pva`` channels (docs/channels.md) come from here unless configuration
says otherwise. The backend keeps one p4p client context per server
address (``host:port``, searched over TCP with ``EPICS_PVA_NAME_SERVERS``;
None: the environment's ``EPICS_PVA_*`` settings), made on first use, and
makes :class:`~.client_channel.PvaChannel`\\s on them. It finds a lost
server again within a second (:meth:`PvaBackend.watch`).

Beyond the protocol, the backend gets values (:meth:`PvaBackend.get`),
puts structures (:meth:`PvaBackend.put`) and calls methods
(:meth:`PvaBackend.rpc`), each awaited on the loop without holding a
thread: p4p's completion callback hands the result over with
:func:`malcolm.core.threads.call_threadsafe`.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Mapping
from typing import Any

from p4p import Value
from p4p.client import raw

from malcolm.core.threads import call_threadsafe

from ..backends import register_backend
from ..channel import Backend, ChannelError, ConnectionState, DisconnectedError
from .client_channel import PvaChannel, client_conf, parse_address
from .client_convert import remote_error

__all__ = ["RENEW_GRACE", "REVIVE_INTERVAL", "PvaBackend"]

#: seconds between tries of a lost server's port (see PvaBackend.watch)
REVIVE_INTERVAL = 0.5
#: seconds a renewed context has to connect before the port is tried again
RENEW_GRACE = 3.0


class PvaBackend(Backend):
    """pvAccess channels, one p4p client context per server address.

    ``address`` (``host:port``) is where channels made without one look;
    None: the ``EPICS_PVA_*`` environment.
    """

    name = "p4p"

    def __init__(self, address: str | None = None) -> None:
        self.address = address
        self._contexts: dict[str | None, raw.Context] = {}
        self._channels: list[PvaChannel] = []
        self._revivers: dict[str, asyncio.Future[None]] = {}
        #: address -> operations in flight there (future -> what)
        self._pending: dict[str | None, dict[asyncio.Future[Any], str]] = {}

    def for_address(self, address: str | None) -> PvaBackend:
        """A view of this backend whose channels and calls go to ``address``
        (sharing its contexts)."""
        view = PvaBackend.__new__(PvaBackend)
        view.address = address
        view._contexts = self._contexts
        view._channels = self._channels
        view._revivers = self._revivers
        view._pending = self._pending
        return view

    # ---- finding a server that went away, or is not there yet
    def _waiting(self, address: str) -> list[PvaChannel]:
        return [
            c
            for c in self._channels
            if c.backend.address == address
            and c.state in (ConnectionState.CONNECTING, ConnectionState.DISCONNECTED)
        ]

    def watch(self, channel: PvaChannel) -> None:
        """Look for the server of ``channel``, which is not connected (on the
        loop). p4p retries a name server only every 10 s or so: instead, every
        :data:`REVIVE_INTERVAL` s the backend tries the server's TCP port and,
        once it answers, makes a new context for that address and subscribes
        its channels again, which connect at once."""
        address = self.address
        if address is None:
            return
        task = self._revivers.get(address)
        if task is None or task.done():
            self._revivers[address] = asyncio.ensure_future(self._revive(address))

    async def _revive(self, address: str) -> None:
        host, port = parse_address(address)
        await asyncio.sleep(REVIVE_INTERVAL)
        while self._waiting(address):
            try:
                _, writer = await asyncio.wait_for(
                    asyncio.open_connection(host, port), REVIVE_INTERVAL
                )
            except (OSError, TimeoutError):
                await asyncio.sleep(REVIVE_INTERVAL)
                continue
            writer.close()
            with contextlib.suppress(OSError):
                await writer.wait_closed()
            waiting = self._waiting(address)
            if not waiting:
                return
            old = self._contexts.pop(address, None)
            for channel in [c for c in self._channels if c.backend.address == address]:
                if channel.state is not ConnectionState.CLOSED:
                    channel._renew()
            if old is not None:
                old.close()
            await asyncio.sleep(RENEW_GRACE)  # time to connect before trying again

    def where(self, name: str = "") -> str:
        """``pva://host:port/name``, as messages name a channel."""
        return f"pva://{self.address or ''}/{name}"

    def context(self) -> raw.Context:
        context = self._contexts.get(self.address)
        if context is None:
            if self.address is None:
                context = raw.Context("pva", nt=False, useenv=True)
            else:
                conf = client_conf(self.address)
                context = raw.Context("pva", conf=conf, useenv=False, nt=False)
            self._contexts[self.address] = context
        return context

    def channel(
        self, read: str, write: str | None = None, *, default: Any = None
    ) -> PvaChannel:
        channel = PvaChannel(self, read, write)
        self._channels.append(channel)
        return channel

    # ---- operations, awaited on the loop
    async def _operation(self, what: str, start: Any) -> Any:
        loop = asyncio.get_running_loop()
        future: asyncio.Future[Any] = loop.create_future()

        def done(result: Any) -> None:
            if future.done():
                return
            if isinstance(result, raw.RemoteError):
                future.set_exception(remote_error(str(result), what))
            elif isinstance(result, raw.Cancelled):
                future.set_exception(DisconnectedError(f"{what}: cancelled"))
            elif isinstance(result, Exception):
                future.set_exception(
                    ChannelError(f"{what}: {type(result).__name__}: {result}")
                )
            else:
                future.set_result(result)

        def handler(result: Any) -> None:  # a p4p thread
            if not loop.is_closed():
                call_threadsafe(loop, done, result)

        op = start(handler)
        pending = self._pending.setdefault(self.address, {})
        pending[future] = what
        try:
            return await future
        finally:
            pending.pop(future, None)
            op.close()

    def fail_pending(self, message: str) -> None:
        """Fail every get, put and call in flight to this address (its
        connection was lost: p4p would keep them waiting for the server)."""
        for future, what in list(self._pending.get(self.address, {}).items()):
            if not future.done():
                future.set_exception(
                    DisconnectedError(
                        f"{what}: {message} before it was done (whether the server"
                        " did it is not known)"
                    )
                )

    async def get(self, name: str, request: str | None = None) -> Value:
        """The current value of channel ``name``."""
        context = self.context()
        return await self._operation(
            self.where(name), lambda h: context.get(name, h, request=request)
        )

    async def put(
        self, name: str, value: Mapping[str, Any], request: str | None = None
    ) -> None:
        """Put the fields of ``value`` (a dict by field name) to channel
        ``name``, returning when the server has done it."""
        context = self.context()
        await self._operation(
            self.where(name),
            lambda h: context.put(name, h, builder=dict(value), request=request),
        )

    async def rpc(self, name: str, args: Value, request: str | None = None) -> Value:
        """Call channel ``name`` with ``args``; what the server returns."""
        context = self.context()
        return await self._operation(
            self.where(name), lambda h: context.rpc(name, h, args, request=request)
        )

    async def close(self) -> None:
        for task in self._revivers.values():
            task.cancel()
        self._revivers.clear()
        for channel in list(self._channels):
            await channel.close()
        self._channels.clear()
        for context in self._contexts.values():
            context.close()
        self._contexts.clear()


register_backend("pva", "p4p", PvaBackend, default=True)

"""The ``pva`` channel backend: pvAccess channels on a p4p client.

``register_backend("pva", "p4p", PvaBackend, default=True)``: a process's
``pva`` channels (docs/channels.md) come from here unless configuration
says otherwise. The backend keeps one p4p client context per server
address (``host:port``, searched over TCP with ``EPICS_PVA_NAME_SERVERS``;
None: the environment's ``EPICS_PVA_*`` settings), made on first use.

A :class:`PvaChannel` monitors one pvAccess channel (``MRI`` for a whole
block, ``MRI.field`` for one field). Its readings' values are the plain
data of what the server sent (:func:`~.client_convert.to_plain`); a
:class:`StructureReading` also says which top-level fields changed (the
first update after every (re)connection is the whole structure, ``changed``
None). A lost server is ``DISCONNECTED`` (p4p goes on searching and
reconnects by itself). p4p calls back in its own threads: every callback
hands its work to the loop with :func:`malcolm.core.threads.call_threadsafe`
(through ``Channel._publish``/``_set_state`` or :meth:`PvaBackend.call`).

Beyond the protocol, the backend calls methods (:meth:`PvaBackend.rpc`) and
puts structures (:meth:`PvaBackend.put`), each awaited on the loop without
holding a thread.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Mapping
from dataclasses import dataclass
from functools import partial
from typing import Any

from p4p import Value
from p4p.client import raw

from malcolm.core import Alarm, TimeStamp
from malcolm.core.threads import call_threadsafe

from ..backends import register_backend
from ..channel import (
    Backend,
    Channel,
    ChannelError,
    ChannelInfo,
    ConnectionState,
    DisconnectedError,
    Reading,
)
from .client_convert import remote_error
from .convert import to_dict as to_plain

__all__ = [
    "DEFAULT_PORT",
    "PvaBackend",
    "PvaChannel",
    "StructureReading",
    "client_conf",
    "parse_address",
]

DEFAULT_PORT = 5075
#: seconds without a reply before p4p gives a connection up (pvxs: echo
#: every CONN_TMO/2 s); a killed server is seen at once (its socket closes)
CONN_TMO = 4.0
#: seconds between tries of a lost server's port (see PvaBackend.watch)
REVIVE_INTERVAL = 0.5
#: seconds a renewed context has to connect before the port is tried again
RENEW_GRACE = 3.0


def parse_address(address: str) -> tuple[str, int]:
    """``host[:port]`` -> (host, port); ValueError naming what is wrong."""
    host, sep, port = str(address).strip().rpartition(":")
    if not sep:
        host, port = port, str(DEFAULT_PORT)
    if not host:
        raise ValueError(f"pvAccess address {address!r} has no host")
    try:
        number = int(port)
    except ValueError:
        raise ValueError(
            f"pvAccess address {address!r}: port {port!r} is not a number"
        ) from None
    if not 0 < number < 65536:
        raise ValueError(f"pvAccess address {address!r}: port {number} out of range")
    return host, number


def client_conf(address: str) -> dict[str, str]:
    """The p4p client configuration that talks to the server at ``address``
    (over TCP, no UDP search)."""
    host, port = parse_address(address)
    return {
        "EPICS_PVA_NAME_SERVERS": f"{host}:{port}",
        "EPICS_PVA_ADDR_LIST": "",
        "EPICS_PVA_AUTO_ADDR_LIST": "NO",
        "EPICS_PVA_CONN_TMO": str(CONN_TMO),
    }


@dataclass(frozen=True)
class StructureReading(Reading):
    """A reading of a structure: ``changed`` names the top-level fields this
    update changed (None: everything, the first update after connecting)."""

    changed: frozenset[str] | None = None


def _alarm_time(data: Any) -> tuple[Alarm, TimeStamp]:
    if isinstance(data, dict):
        alarm = data.get("alarm")
        stamp = data.get("timeStamp")
        return (
            Alarm.from_dict(alarm) if isinstance(alarm, dict) else Alarm.ok,
            TimeStamp.from_dict(stamp) if isinstance(stamp, dict) else TimeStamp.now(),
        )
    return Alarm.ok, TimeStamp.now()


class PvaChannel(Channel):
    """One pvAccess channel, monitored; see the module's docstring."""

    def __init__(self, backend: PvaBackend, read: str, write: str | None) -> None:
        super().__init__(read, write)
        self.backend = backend
        self._sub: Any = None
        self._last: Any = None
        self._fresh = True  # the next update is the whole structure

    @property
    def where(self) -> str:
        return self.backend.where(self.read)

    async def _start(self) -> None:
        context = self.backend.context()
        loop = asyncio.get_running_loop()
        self._sub = raw.Subscription(
            context._ctxt,
            self.read,
            context._nt,
            handler=partial(self._woken, loop),
            pvRequest=None,
        )
        self.backend.watch(self)

    def _renew(self) -> None:
        """Subscribe again, on the backend's new context (see
        :meth:`PvaBackend.watch`); the next update is the whole structure."""
        sub, self._sub = self._sub, None
        if sub is not None:
            sub.close()
        self._fresh = True
        context = self.backend.context()
        loop = self._loop
        assert loop is not None
        self._sub = raw.Subscription(
            context._ctxt,
            self.read,
            context._nt,
            handler=partial(self._woken, loop),
            pvRequest=None,
        )

    def _woken(self, loop: asyncio.AbstractEventLoop) -> None:
        # a p4p thread: the queue has something; drain it on the loop
        if not loop.is_closed():
            call_threadsafe(loop, self._drain)

    def _drain(self) -> None:
        sub = self._sub
        while sub is not None and self._state is not ConnectionState.CLOSED:
            item = sub.pop()
            if item is None:
                return
            if isinstance(item, Exception):
                self._fresh = True
                if isinstance(item, raw.Disconnected):
                    message = "connection lost"
                else:
                    message = f"{type(item).__name__}: {item}"
                if self._state is ConnectionState.CONNECTED:
                    self._set_state(ConnectionState.DISCONNECTED, message)
                    self.backend.fail_pending(message)
                    self.backend.watch(self)
                else:
                    self._message = message
                continue
            self._update(item)

    def _update(self, value: Value) -> None:
        if self._fresh:
            changed: frozenset[str] | None = None
            data = to_plain(value)
        else:
            changed = frozenset(p.split(".", 1)[0] for p in value.changedSet())
            if not changed:
                return
            data = dict(self._last or {})
            for key in changed:
                data[key] = to_plain(value[key])
        self._last = data
        alarm, stamp = _alarm_time(data)
        reading = StructureReading(
            data.get("value") if _is_nt(data) else data, alarm, stamp, changed
        )
        if self._fresh:
            self._fresh = False
            self._set_state(ConnectionState.CONNECTED)
        self._publish(reading)

    async def _info(self) -> ChannelInfo:
        meta = (self._last or {}).get("meta")
        if not isinstance(meta, dict):
            return ChannelInfo()
        display = meta.get("display") or {}
        limits = None
        if display and display.get("limitLow") != display.get("limitHigh"):
            limits = (display.get("limitLow"), display.get("limitHigh"))
        choices = meta.get("choices")
        return ChannelInfo(
            limits=limits,
            units=display.get("units") or None,
            precision=display.get("precision"),
            choices=tuple(choices) if isinstance(choices, list) else None,
            writeable=meta.get("writeable"),
        )

    async def get(self) -> Reading:
        self.check_connected()
        data = to_plain(await self.backend.get(self.read))
        alarm, stamp = _alarm_time(data)
        return Reading(data.get("value") if _is_nt(data) else data, alarm, stamp)

    async def _put(self, value: Any) -> None:
        assert self.write is not None
        await self.backend.put(self.write, {"value": value})

    async def _close(self) -> None:
        sub, self._sub = self._sub, None
        if sub is not None:
            sub.close()


def _is_nt(data: Any) -> bool:
    return isinstance(data, dict) and str(data.get("typeid", "")).startswith(
        "epics:nt/NTScalar"
    )


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

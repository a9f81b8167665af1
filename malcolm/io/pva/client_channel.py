"""pvAccess channels on a p4p client (the ``pva`` backend's channels).

The backend, :class:`~.client_backend.PvaBackend`, makes them and keeps
their p4p contexts. A :class:`PvaChannel` monitors one pvAccess channel
(``MRI`` for a whole block, ``MRI.field`` for one field). Its readings'
values are the plain data of what the server sent
(:func:`~.convert.to_dict`): an NT field's value, or the whole structure
as a dict; a :class:`StructureReading` also says which top-level fields
changed (the first update after every (re)connection is the whole
structure, ``changed`` None). A lost server makes the channel
``DISCONNECTED`` until it is back. p4p calls back in its own threads:
every callback hands its work to the loop with
:func:`malcolm.core.threads.call_threadsafe` (through
``Channel._publish``/``_set_state``).
"""

from __future__ import annotations

import asyncio
from dataclasses import dataclass
from functools import partial
from typing import TYPE_CHECKING, Any

from p4p import Value
from p4p.client import raw

from malcolm.core import Alarm, TimeStamp
from malcolm.core.threads import call_threadsafe

from ..channel import Channel, ChannelInfo, ConnectionState, Reading
from .convert import to_dict as to_plain

if TYPE_CHECKING:
    from .client_backend import PvaBackend

__all__ = [
    "CONN_TMO",
    "DEFAULT_PORT",
    "PvaChannel",
    "StructureReading",
    "client_conf",
    "parse_address",
]

DEFAULT_PORT = 5075
#: seconds without a reply before p4p gives a connection up (pvxs: echo
#: every CONN_TMO/2 s); a killed server is seen at once (its socket closes)
CONN_TMO = 4.0


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

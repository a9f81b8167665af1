"""The soft backend: channels on in-memory records, no hardware.

Each name (a PV) is a :class:`SoftRecord` holding a value, an alarm and a
timeStamp; one :class:`SoftBackend` per process holds its records. A put
through a channel sets the record written to and, at once, its readback
(the record read from), so a readback follows its demand; ``follow`` on the
readback's record can change what the readback becomes (an IOC that rounds
or clamps).

The backend also stands in for the world, for tests and simulations. Call
these on the process's loop (from another thread, through
``process.call_threadsafe``):

- ``set(name, value, alarm)``: the hardware changed a value;
- ``drop(name, message)`` / ``restore(name)``: the connection to a record is
  lost / back (every channel touching it is DISCONNECTED, then CONNECTED
  again and its subscribers get the current value);
- ``hold_puts(name)`` / ``release_puts(name)``: puts to a record do not
  complete until released;
- ``hold_monitors(name)`` / ``release_monitors(name)``: a record's changes
  reach subscribers only when released (a monitor that lags a put's
  completion, as Channel Access monitors may).
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from dataclasses import replace
from typing import Any

from malcolm.core import Alarm, TimeStamp

from .channel import (
    Backend,
    Channel,
    ChannelInfo,
    ConnectionState,
    DisconnectedError,
    Reading,
)

__all__ = ["SoftBackend", "SoftChannel", "SoftRecord"]


class SoftRecord:
    """One in-memory PV: value, alarm, timeStamp, and what a channel's
    connect reports about it (``info``)."""

    def __init__(self, name: str, value: Any = None) -> None:
        self.name = name
        self.value = value
        self.alarm = Alarm.ok
        self.timeStamp = TimeStamp.now()
        self.info = ChannelInfo()
        self.connected = True
        self.lost = "connection lost"
        #: completed puts to this record, and gets of it
        self.puts = 0
        self.gets = 0
        #: what this record becomes when a put to its demand sets it
        self.follow: Callable[[Any], Any] | None = None
        self._held_puts: asyncio.Event | None = None
        self._held_monitors = False

    def reading(self) -> Reading:
        return Reading(self.value, self.alarm, self.timeStamp)

    def __repr__(self) -> str:
        return f"<SoftRecord {self.name}={self.value!r}>"


class SoftChannel(Channel):
    """A channel on the records of a :class:`SoftBackend`."""

    def __init__(self, backend: SoftBackend, read: str, write: str | None) -> None:
        super().__init__(read, write)
        self.backend = backend

    @property
    def records(self) -> list[SoftRecord]:
        """The records this channel reads (first) and writes."""
        names = [self.read] + ([self.write] if self.write else [])
        return [self.backend.records[n] for n in dict.fromkeys(names)]

    def _lost(self) -> str | None:
        for record in self.records:
            if not record.connected:
                return f"{record.name}: {record.lost}"
        return None

    async def _start(self) -> None:
        self.backend.refresh(self)

    async def _info(self) -> ChannelInfo:
        read = self.backend.records[self.read]
        if read.info == ChannelInfo() and self.write is not None:
            return self.backend.records[self.write].info
        return read.info

    async def get(self) -> Reading:
        self.check_connected()
        record = self.backend.records[self.read]
        record.gets += 1
        return record.reading()

    async def _put(self, value: Any) -> None:
        assert self.write is not None
        demand = self.backend.records[self.write]
        if demand._held_puts is not None:
            await demand._held_puts.wait()
        lost = self._lost()
        if lost is not None:
            raise DisconnectedError(f"{self.name}: {lost}")
        readback = self.backend.records[self.read]
        now = TimeStamp.now()
        demand.value, demand.timeStamp = value, now
        if readback is not demand or readback.follow is not None:
            follow = readback.follow
            readback.value = follow(value) if follow is not None else value
            readback.timeStamp = now
        demand.puts += 1
        self.backend.changed(demand)
        if readback is not demand:
            self.backend.changed(readback)

    async def _close(self) -> None:
        self.backend.forget(self)


class SoftBackend(Backend):
    """In-memory records and the channels on them (one per process)."""

    name = "soft"

    def __init__(self) -> None:
        self.records: dict[str, SoftRecord] = {}
        self._channels: list[SoftChannel] = []

    # ---- records
    def record(self, name: str, default: Any = None) -> SoftRecord:
        """The record called ``name``, made (holding ``default``) if new."""
        record = self.records.get(name)
        if record is None:
            record = self.records[name] = SoftRecord(name, default)
        elif record.value is None and default is not None:
            record.value = default
        return record

    def define(
        self,
        name: str,
        value: Any = None,
        *,
        limits: tuple[float, float] | None = None,
        units: str | None = None,
        precision: int | None = None,
        choices: tuple[str, ...] | list[str] | None = None,
        follow: Callable[[Any], Any] | None = None,
    ) -> SoftRecord:
        """Make (or change) a record with what connect will report about it."""
        record = self.record(name)
        if value is not None:
            record.value = value
        record.info = replace(
            record.info,
            limits=limits,
            units=units,
            precision=precision,
            choices=tuple(choices) if choices is not None else None,
        )
        record.follow = follow
        return record

    def channel(
        self, read: str, write: str | None = None, *, default: Any = None
    ) -> SoftChannel:
        self.record(read, default)
        if write is not None:
            self.record(write, default)
        channel = SoftChannel(self, read, write)
        self._channels.append(channel)
        return channel

    # ---- the world changes
    def set(self, name: str, value: Any, alarm: Alarm = Alarm.ok) -> None:
        """The hardware changed ``name`` to ``value`` (with ``alarm``)."""
        record = self.record(name)
        record.value, record.alarm, record.timeStamp = value, alarm, TimeStamp.now()
        self.changed(record)

    def drop(self, name: str, message: str = "connection lost") -> None:
        """The connection to ``name`` is lost."""
        record = self.record(name)
        record.connected, record.lost = False, message
        for channel in self._touching(record):
            self.refresh(channel)

    def restore(self, name: str) -> None:
        """The connection to ``name`` is back."""
        record = self.record(name)
        record.connected = True
        for channel in self._touching(record):
            self.refresh(channel)

    def hold_puts(self, name: str) -> None:
        """Puts to ``name`` wait (incomplete) until ``release_puts``."""
        self.record(name)._held_puts = asyncio.Event()

    def release_puts(self, name: str) -> None:
        record = self.record(name)
        held, record._held_puts = record._held_puts, None
        if held is not None:
            held.set()

    def hold_monitors(self, name: str) -> None:
        """Changes of ``name`` reach subscribers only at ``release_monitors``."""
        self.record(name)._held_monitors = True

    def release_monitors(self, name: str) -> None:
        record = self.record(name)
        record._held_monitors = False
        self.changed(record)

    # ---- for the channels
    def changed(self, record: SoftRecord) -> None:
        """Give ``record``'s reading to the connected channels that read it."""
        if record._held_monitors:
            return
        for channel in list(self._channels):
            if (
                channel.read == record.name
                and channel.state is ConnectionState.CONNECTED
            ):
                channel._publish(record.reading())

    def refresh(self, channel: SoftChannel) -> None:
        """Bring a (connecting) channel's state in line with its records."""
        if channel.state in (ConnectionState.IDLE, ConnectionState.CLOSED):
            return
        lost = channel._lost()
        if lost is None and channel.state is not ConnectionState.CONNECTED:
            channel._set_state(ConnectionState.CONNECTED)
            channel._publish(self.records[channel.read].reading())
        elif lost is not None and channel.state is ConnectionState.CONNECTED:
            channel._set_state(ConnectionState.DISCONNECTED, lost)
        elif lost is not None:
            channel._set_state(ConnectionState.CONNECTING, lost)

    def forget(self, channel: SoftChannel) -> None:
        if channel in self._channels:
            self._channels.remove(channel)

    def _touching(self, record: SoftRecord) -> list[SoftChannel]:
        return [c for c in self._channels if record.name in (c.read, c.write)]

    async def close(self) -> None:
        for channel in list(self._channels):
            await channel.close()

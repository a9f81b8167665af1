"""ChannelPart: one attribute kept in step with a channel (:mod:`malcolm.io`).

The part takes its channel from the backend its process chose for its
transport (:func:`malcolm.io.backend_for`), never builds one itself. In the
block's Reset phase (so when the process starts, and at every reset) it
connects: the channel's readings become the attribute's value, alarm and
timeStamp, and what the channel reports at connect (limits, units,
precision, choices) fills the meta where the definition left them open.

When the connection is lost the attribute's alarm becomes
``Alarm.disconnected`` (INVALID) and the block's ``health`` names the
channel (``part: message``); both recover when it comes back, without a
restart. A put (writeable attributes) is a put with completion, followed by
a get of the readback, so the attribute shows what the readback says once
the put is done, not a monitor update that may still be on its way (the
design document's "doing a get on the RBV value to avoid the race
condition"). The Disable phase closes the channel.
"""

from __future__ import annotations

import asyncio
import weakref
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, ClassVar

from malcolm.core import Alarm, AlarmStatus, Attribute, BadValueError, Meta
from malcolm.fsm import Stateful
from malcolm.io import (
    Channel,
    ChannelError,
    ChannelInfo,
    ChannelTimeoutError,
    ConnectionState,
    DisconnectedError,
    Reading,
    backend_for,
)

from .base import Part, PartRegistrar

if TYPE_CHECKING:
    from malcolm.hooks import Task

__all__ = ["CONNECT_TIMEOUT", "ChannelPart"]

#: seconds a Reset waits for a channel to connect before going on without it
#: (the channel goes on trying; health says it is not connected)
CONNECT_TIMEOUT = 5.0

NOT_CONNECTED = "not connected yet"


#: backends already asked to prefetch their process's channels
_prefetched: weakref.WeakSet[Any] = weakref.WeakSet()


def _prefetch(backend: Any, process: Any, transport: str) -> None:
    """Let a backend that can (``prefetch(names)``, the pyepics one) start
    connecting every channel of the process's ChannelParts at the first
    Reset: blocks start one after another, their channels then connect
    together rather than one block's at a time."""
    prefetch = getattr(backend, "prefetch", None)
    if prefetch is None or backend in _prefetched:
        return
    _prefetched.add(backend)
    names: dict[str, None] = {}
    for mri in process.mris:
        # not every controller has parts (the pvAccess server's block list)
        parts = getattr(process.get_controller(mri), "parts", None) or {}
        for part in parts.values():
            if isinstance(part, ChannelPart) and part.transport == transport:
                names.update(dict.fromkeys(n for n in (part.read, part.write) if n))
    prefetch(list(names))


class ChannelPart(Part):
    """An attribute read from channel ``read`` and, if writeable, put to
    ``write``; subclasses choose the meta (:meth:`attribute_meta`) and may adjust
    it from what the channel reports (:meth:`meta_from_info`)."""

    #: the transport whose backend makes the channel
    transport: ClassVar[str] = "ca"
    connect_timeout: ClassVar[float] = CONNECT_TIMEOUT

    def __init__(
        self, name: str, read: str, write: str | None = None, writeable: bool = False
    ) -> None:
        super().__init__(name)
        self.read = read
        self.write = write
        self.writeable = bool(writeable)
        #: the channel, once the block has started (kept after it closes)
        self.channel: Channel | None = None
        self.attr: Attribute | None = None
        self._registrar: PartRegistrar | None = None
        self._ends: list[Callable[[], None]] = []
        self._alarm = Alarm.ok  # the alarm of the last reading
        #: the reading the subscription gave since the channel (re)connected
        self._fresh: Reading | None = None
        #: connect() is waiting for the channel (and completes the meta)
        self._connecting = False
        #: the tasks completing the meta on a late connection (kept alive)
        self._late: set[asyncio.Task[None]] = set()

    def attribute_meta(self) -> Meta:
        """The attribute's meta, before the channel reports anything."""
        raise NotImplementedError

    def meta_from_info(self, meta: Meta, info: ChannelInfo) -> Meta | None:
        """A meta completed from what the channel reported, or None for no
        change (the default)."""
        return None

    def setup(self, registrar: PartRegistrar) -> None:
        self._registrar = registrar
        self.attr = registrar.add_attribute(
            self.name,
            self.attribute_meta(),
            put=self.put if self.writeable else None,
            alarm=Alarm.disconnected(f"{self.read}: {NOT_CONNECTED}"),
        )

    # ---- connecting
    @Stateful.Reset
    async def connect(self, task: Task) -> None:
        """Connect (if not connected); a channel that does not connect in
        time is reported in health, and keeps trying."""
        assert self.attr is not None
        channel = self.channel
        if channel is None or channel.state is ConnectionState.CLOSED:
            backend = backend_for(task.process, self.transport)
            _prefetch(backend, task.process, self.transport)
            channel = backend.channel(
                self.read, self.write, default=self.attr.meta.default()
            )
            self.channel = channel
            self._ends = [
                channel.watch_connection(self._on_connection),
                channel.subscribe(self._on_reading),
            ]
        elif channel.state is ConnectionState.CONNECTED:
            return
        self._connecting = True
        try:
            info = await channel.connect(self.connect_timeout)
            # a channel's subscribers get a reading first on connecting: no
            # need to ask again (a CA get each, thousands at start-up)
            reading = self._fresh or await channel.get()
        except ChannelTimeoutError:
            self._on_connection(channel.state, channel.message or NOT_CONNECTED)
            return
        except DisconnectedError as e:  # lost again at once: it keeps trying
            self._on_connection(ConnectionState.DISCONNECTED, str(e))
            return
        finally:
            self._connecting = False
        self._complete_meta(info, reading)

    def _complete_meta(self, info: ChannelInfo, reading: Reading) -> None:
        """The meta completed from ``info``, then ``reading`` shown."""
        assert self.attr is not None
        meta = self.meta_from_info(self.attr.meta, info)
        if meta is not None:
            try:
                self.attr.set_meta(meta, self._value(reading))
            except BadValueError as e:
                self._bad(reading, e)
                return
        self._on_reading(reading)

    @Stateful.Disable
    async def disconnect(self, task: Task) -> None:
        """Close the channel; the attribute shows it is not connected."""
        channel = self.channel
        for end in self._ends:
            end()
        self._ends = []
        if channel is not None:
            await channel.close()
        assert self.attr is not None and self._registrar is not None
        self.attr.set_alarm(Alarm.disconnected(f"{self.read}: closed (disabled)"))
        self._registrar.report_health(None)

    def _on_connection(self, state: ConnectionState, message: str) -> None:
        assert self.attr is not None and self._registrar is not None
        name = self.channel.name if self.channel is not None else self.read
        if state is ConnectionState.CONNECTED:
            self._registrar.report_health(None)
            if self.attr.alarm.status is AlarmStatus.CLIENT_STATUS:
                self.attr.set_alarm(self._alarm)
            if not self._connecting and self.channel is not None:
                # connected after connect() gave up waiting, or again: what
                # the channel reports now completes the meta (the IOC started
                # after malcolm, or came back with other labels or limits)
                task = asyncio.get_running_loop().create_task(
                    self._late_meta(self.channel)
                )
                self._late.add(task)
                task.add_done_callback(self._late.discard)
        elif state in (ConnectionState.CONNECTING, ConnectionState.DISCONNECTED):
            self._fresh = None
            names = [n for n in (self.read, self.write) if n]
            named = any(n in message for n in names)
            text = message if named else f"{name}: {message}"
            self.attr.set_alarm(Alarm.disconnected(text))
            self._registrar.report_health(text)

    async def _late_meta(self, channel: Channel) -> None:
        try:
            info = await channel.connect(0)  # connected: at once
            reading = channel.latest or await channel.get()
        except ChannelError:
            return  # lost again or closed: a next connection tries again
        if channel is self.channel:
            self._complete_meta(info, reading)

    # ---- values
    def _value(self, reading: Reading) -> Any:
        assert self.attr is not None
        if reading.value is None:
            return self.attr.meta.default()
        return reading.value

    def _on_reading(self, reading: Reading) -> None:
        assert self.attr is not None
        channel = self.channel
        if channel is not None and channel.state is ConnectionState.CONNECTED:
            self._fresh = reading
        try:
            value = self.attr.validate(self._value(reading))
        except BadValueError as e:
            self._bad(reading, e)
            return
        self._alarm = reading.alarm
        self.attr.set_value(
            value, alarm=reading.alarm, timeStamp=reading.timeStamp, validate=False
        )

    def _bad(self, reading: Reading, error: BadValueError) -> None:
        """A reading that does not fit the attribute: keep the value, say why."""
        assert self.attr is not None
        name = self.channel.name if self.channel is not None else self.read
        self.attr.set_alarm(Alarm.invalid(f"{name} gave {reading.value!r}: {error}"))

    async def put(self, value: Any) -> None:
        """Put with completion, then show what the readback says."""
        channel = self.channel
        if channel is None:
            raise DisconnectedError(
                f"{self.write or self.read}: not connected (the block has not started)"
            )
        try:
            reading = await channel.put_and_read(value)
        except ChannelError as e:  # the same kind, naming block and field
            assert self._registrar is not None
            raise type(e)(f"{self._registrar.mri}.{self.name}: {e}") from None
        self._on_reading(reading)

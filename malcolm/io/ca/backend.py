"""The pyepics Channel Access backend: channels over :mod:`.link`.

A :class:`PyepicsChannel` reads PV ``read`` and puts to PV ``write`` (one
:class:`~.link.Link` each, or one for both). It is CONNECTED once every PV
it names is connected and has sent its control information, and its
readback its first value; it is DISCONNECTED (and its pending gets and puts
fail) as soon as any of them is lost, and CONNECTED again when they are
back: CA keeps searching, and re-sends the subscriptions' first events.

Every channel of a process's loop that names a PV hears it through one
:class:`PVFanout`, the link's one listener for that loop: each event of the
PV (a value, a connection change, control information) crosses from libca's
thread to the loop once, and there goes to all those channels in the same
loop callback. So when any channel's subscriber sees a value (say an
action waiting for ``DMOV``), every other channel of the PV on the loop
(the block's ``doneMoving``) has been given it too, before any task that
the subscriber woke runs (docs/channels.md).

Values are given in the form the channel's ``default`` asks for (what the
attribute's meta holds): a bool for a bo/bi record read by a ``ca.Bool``, an
enum's label for a ``ca.Enum``, the text of a char waveform for a
``ca.LongString``, a 1-d numpy array for ``ca.DoubleArray``/``ca.LongArray``.
A put converts back (a label to its index, text to chars) and refuses what
the PV cannot take, before anything is written.
"""

from __future__ import annotations

import asyncio
import logging
import math
import threading
import weakref
from collections.abc import Callable, Iterable
from typing import Any

import numpy as np
from epics import dbr

from malcolm.core import Alarm, AlarmSeverity, AlarmStatus, TimeStamp

from ..channel import (
    Backend,
    Channel,
    ChannelError,
    ChannelInfo,
    ChannelTimeoutError,
    ConnectionState,
    DisconnectedError,
    Reading,
)
from .link import Link, Payload, link

__all__ = ["GET_TIMEOUT", "PVFanout", "PyepicsBackend", "PyepicsChannel"]

log = logging.getLogger(__name__)

#: seconds a get waits for the IOC's answer
GET_TIMEOUT = 5.0

#: EPICS alarm conditions (the ``STAT`` field) by number
CONDITIONS = (
    "NO_ALARM READ WRITE HIHI HIGH LOLO LOW STATE COS COMM TIMEOUT HWLIMIT CALC"
    " SCAN LINK SOFT BAD_SUB UDF DISABLE SIMM READ_ACCESS WRITE_ACCESS"
).split()
_DEVICE = {"READ", "WRITE", "COMM", "TIMEOUT", "HWLIMIT", "LINK", "SCAN"}

_ENUM, _CHAR, _STRING = dbr.ENUM, dbr.CHAR, dbr.STRING


def alarm_of(metadata: dict[str, Any]) -> Alarm:
    """The malcolm Alarm of a TIME event's severity and status."""
    severity = int(metadata.get("severity", 0))
    if severity <= 0:
        return Alarm.ok
    code = int(metadata.get("status", 0))
    name = CONDITIONS[code] if 0 <= code < len(CONDITIONS) else f"STAT {code}"
    if name == "UDF":
        status = AlarmStatus.UNDEFINED_STATUS
    elif name in _DEVICE:
        status = AlarmStatus.DEVICE_STATUS
    else:
        status = AlarmStatus.RECORD_STATUS
    return Alarm(AlarmSeverity(min(severity, 3)), status, name)


def timestamp_of(metadata: dict[str, Any]) -> TimeStamp:
    if "posixseconds" not in metadata:
        return TimeStamp.now()
    return TimeStamp(int(metadata["posixseconds"]), int(metadata["nanoseconds"]))


def _limits(md: dict[str, Any], low: str, high: str) -> tuple[float, float] | None:
    lo, hi = md.get(f"lower_{low}_limit"), md.get(f"upper_{high}_limit")
    if lo is None or hi is None or not (math.isfinite(lo) and math.isfinite(hi)):
        return None
    return (float(lo), float(hi)) if lo < hi else None


def info_of(ftype: int | None, md: dict[str, Any]) -> dict[str, Any]:
    """ChannelInfo fields from a CTRL event's metadata."""
    found: dict[str, Any] = {}
    if ftype == _ENUM:
        found["choices"] = tuple(md.get("enum_strs", ()))
        return found
    if ftype == _STRING:
        return found
    limits = _limits(md, "ctrl", "ctrl") or _limits(md, "disp", "disp")
    if limits is not None:
        found["limits"] = limits
    if md.get("units"):
        found["units"] = md["units"]
    if ftype in (dbr.DOUBLE, dbr.FLOAT) and "precision" in md:
        found["precision"] = int(md["precision"])
    return found


class PVFanout:
    """The one listener of a :class:`~.link.Link` for the channels of one
    asyncio loop: hands each event to the loop once (one :func:`to_loop`
    hop) and there gives it to
    every channel in turn, in one loop callback.

    It keeps what it last gave on the loop (connected, control information,
    value), so a channel that joins later is told exactly that, in order
    with the events still on their way to the loop.
    """

    def __init__(self, pv: Link, loop: asyncio.AbstractEventLoop) -> None:
        self.link = pv
        self.loop = loop
        self.channels: list[PyepicsChannel] = []
        self._up = False
        self._info: tuple[int | None, dict[str, Any]] | None = None
        self._value: Payload | None = None

    # ---- from libca's threads (or the loop's, when attaching)
    def link_connection(self, link: Link, up: bool) -> None:
        self._hop(self._connection, up)

    def link_value(self, link: Link, payload: Payload) -> None:
        self._hop(self._value_event, payload)

    def link_info(self, link: Link, payload: Payload) -> None:
        self._hop(self._info_event, link.ftype, payload[1])

    def _hop(self, func: Callable[..., None], *args: Any) -> None:
        to_loop(self.loop, func, *args)

    # ---- on the loop: one callback per event, every channel
    def _connection(self, up: bool) -> None:
        self._up = up
        if not up:
            self._info = self._value = None
        for channel in list(self.channels):
            channel._logged(channel._connection, self.link.name, up)

    def _info_event(self, ftype: int | None, md: dict[str, Any]) -> None:
        self._info = (ftype, md)
        for channel in list(self.channels):
            channel._logged(channel._info_event, self.link.name, ftype, md)

    def _value_event(self, payload: Payload) -> None:
        self._value = payload
        for channel in list(self.channels):
            if channel.read == self.link.name:
                channel._logged(channel._value, payload)

    # ---- channels joining and leaving (on the loop)
    def add(self, channel: PyepicsChannel) -> None:
        """Give ``channel`` this PV's events from now on; tell it what the
        loop knows already. The first channel attaches to the link."""
        self.channels.append(channel)
        if len(self.channels) == 1:
            self.link.attach(self)  # tells what it knows: through _hop, at once
            return
        if self._up:
            channel._logged(channel._connection, self.link.name, True)
            if self._info is not None:
                channel._logged(channel._info_event, self.link.name, *self._info)
            if self._value is not None and channel.read == self.link.name:
                channel._logged(channel._value, self._value)

    def remove(self, channel: PyepicsChannel) -> None:
        """Stop telling ``channel``; the last one out detaches from the link."""
        if channel in self.channels:
            self.channels.remove(channel)
        if not self.channels:
            _fanouts.pop((self.link.name, self.loop), None)
            self.link.detach(self)


class _Inbox:
    """What libca's threads hand to one loop, in the order they hand it: one
    ``call_soon_threadsafe`` (one wake-up of the loop, one write to its
    self-pipe) for all that arrives before the loop takes it, not one each.
    The loop runs what it found in one callback, then (if more came
    meanwhile) again after its other ready work."""

    def __init__(self, loop: asyncio.AbstractEventLoop) -> None:
        self.loop = loop
        self.items: list[tuple[Callable[..., None], tuple[Any, ...]]] = []
        self.lock = threading.Lock()
        self.due = False  # a drain is scheduled on the loop

    def put(self, func: Callable[..., None], args: tuple[Any, ...]) -> None:
        with self.lock:
            self.items.append((func, args))
            if self.due:
                return
            self.due = True
        try:
            self.loop.call_soon_threadsafe(self.drain)
        except RuntimeError:  # closed meanwhile: nobody listens
            pass

    def drain(self) -> None:
        with self.lock:
            items, self.items = self.items, []
        for func, args in items:
            try:
                func(*args)
            except Exception:
                log.exception("handing a Channel Access event to the loop failed")
        with self.lock:
            if not self.items:
                self.due = False
                return
        self.loop.call_soon(self.drain)  # more came: after the loop's other work


_inboxes: weakref.WeakKeyDictionary[asyncio.AbstractEventLoop, _Inbox] = (
    weakref.WeakKeyDictionary()
)
_inboxes_lock = threading.Lock()


def to_loop(
    loop: asyncio.AbstractEventLoop, func: Callable[..., None], *args: Any
) -> None:
    """Run ``func(*args)`` on ``loop``: at once on the loop's own thread, else
    through the loop's inbox (nothing if the loop is closed).

    The short road of docs/channels.md's thread-to-loop paths, for what
    libca's threads hand over (events, get and put answers): plain functions
    whose result nobody waits for, so no Future is made in libca's thread
    and settled on the loop, as :func:`~malcolm.core.threads.call_threadsafe`
    does, and one wake-up of the loop for all that arrives before it runs
    (:class:`_Inbox`), in order; what they change, they change on the loop."""
    if asyncio._get_running_loop() is loop:
        func(*args)
        return
    if loop.is_closed():
        return
    inbox = _inboxes.get(loop)
    if inbox is None:
        with _inboxes_lock:
            inbox = _inboxes.setdefault(loop, _Inbox(loop))
    inbox.put(func, args)


#: (PV name, loop) -> the fanout of that PV's channels on that loop
_fanouts: dict[tuple[str, asyncio.AbstractEventLoop], PVFanout] = {}


def fanout(pv: Link, loop: asyncio.AbstractEventLoop) -> PVFanout:
    """The one fanout of ``pv`` for ``loop`` (called on ``loop``)."""
    key = (pv.name, loop)
    found = _fanouts.get(key)
    if found is None:
        found = _fanouts[key] = PVFanout(pv, loop)
    return found


class PyepicsChannel(Channel):
    """A CA channel: monitors ``read``, puts with callback to ``write``.

    Its PVs' events come from their :class:`PVFanout` of the channel's loop,
    on the loop."""

    def __init__(self, read: str, write: str | None, default: Any) -> None:
        super().__init__(read, write)
        self._default = default
        names = [read] if write in (None, read) else [read, write]
        self._links: dict[str, Link] = {name: link(name) for name in names}
        self._up: dict[str, bool] = dict.fromkeys(names, False)
        self._infos: dict[str, dict[str, Any]] = {}
        #: the readback's last value event, converted once connected (an
        #: enum's labels may arrive after its first value)
        self._payload: Payload | None = None
        self._pending: set[asyncio.Future[Any]] = set()
        self._ever = False  # connected once: a loss is "connection lost"

    def _on_loop(self, func: Callable[..., None], *args: Any) -> None:
        if self._loop is not None:
            to_loop(self._loop, self._logged, func, *args)

    def _logged(self, func: Callable[..., None], *args: Any) -> None:
        try:
            func(*args)
        except Exception:
            log.exception("%s: handling a Channel Access event failed", self.name)

    # ---- on the loop (from the fanouts, or a get's or put's answer)
    def _connection(self, name: str, up: bool) -> None:
        self._up[name] = up
        if up:
            return  # ready once its info (and value) arrive
        self._infos.pop(name, None)
        if name == self.read:
            self._payload = None
        why = "connection lost" if self._ever else "not connected yet"
        self._fail_pending(DisconnectedError(f"{name}: {why}"))
        state = ConnectionState.DISCONNECTED if self._ever else self.state
        if self.state is not ConnectionState.CLOSED:
            self._change_state(state, f"{name}: {why}")

    def _info_event(self, name: str, ftype: int | None, md: dict[str, Any]) -> None:
        self._infos[name] = {"ftype": ftype, **info_of(ftype, md)}
        self._check_ready()

    def _value(self, payload: Payload) -> None:
        self._payload = payload
        if self.state is ConnectionState.CONNECTED:
            self._deliver(self._convert(payload))
        else:
            self._check_ready()

    def _check_ready(self) -> None:
        if self.state is ConnectionState.CONNECTED or self._payload is None:
            return
        if all(self._up.values()) and set(self._infos) == set(self._links):
            self._ever = True
            self._change_state(ConnectionState.CONNECTED, "")
            if self.state is ConnectionState.CONNECTED:
                self._deliver(self._convert(self._payload))

    def _fail_pending(self, error: Exception) -> None:
        for fut in list(self._pending):
            if not fut.done():
                fut.set_exception(error)
        self._pending.clear()

    # ---- values
    def _convert(self, payload: Payload) -> Reading:
        value, md = payload
        return Reading(self._shape(value), alarm_of(md), timestamp_of(md))

    def _choices(self, name: str) -> tuple[str, ...]:
        return tuple(self._infos.get(name, {}).get("choices", ()))

    def _shape(self, value: Any) -> Any:
        """The PV's value in the form of the channel's default."""
        default = self._default
        kind, wanted = type(value), type(default)
        if (kind is float or kind is int) and (wanted is float or wanted is int):
            return wanted(value)  # a scalar number (most events): at once
        ftype = self._links[self.read].ftype
        if isinstance(default, bool):
            return bool(np.asarray(value).ravel()[0]) if np.size(value) else False
        if isinstance(default, str):
            if ftype == _ENUM:
                choices = self._choices(self.read)
                index = int(value)
                return choices[index] if 0 <= index < len(choices) else str(index)
            if ftype == _CHAR and not isinstance(value, np.ndarray):
                value = np.atleast_1d(value)  # a one-char waveform
            if isinstance(value, np.ndarray):
                raw = value.astype(np.uint8).tobytes()
                return raw.split(b"\0", 1)[0].decode("utf-8", "replace")
            return "" if value is None else str(value)
        if isinstance(default, np.ndarray | list | tuple):
            return np.atleast_1d(np.asarray(value))
        if isinstance(value, np.ndarray) and value.size == 1:
            value = value[0]
        if isinstance(default, int) and not isinstance(value, str):
            return int(value)
        if isinstance(default, float) and not isinstance(value, str):
            return float(value)
        return value

    def _to_pv(self, value: Any) -> Any:
        """``value`` as the write PV takes it; ChannelError if it cannot."""
        assert self.write is not None
        target = self._links[self.write]
        ftype = target.ftype
        if ftype == _ENUM:
            if isinstance(value, str):
                choices = self._choices(self.write)
                if value not in choices:
                    raise ChannelError(
                        f"{self.write}: {value!r} is not one of {list(choices)}"
                    )
                return choices.index(value)
            return int(value)
        if ftype == _CHAR and target.count > 1 and isinstance(value, str):
            encoded = value.encode("utf-8")
            if len(encoded) >= target.count:
                raise ChannelError(
                    f"{self.write}: text of {len(encoded)} bytes does not fit"
                    f" in {target.count - 1}"
                )
            return np.frombuffer(encoded + b"\0", dtype=np.uint8)
        if isinstance(value, bool):
            return int(value)
        if isinstance(value, np.ndarray | list | tuple):
            if len(value) > target.count:
                raise ChannelError(
                    f"{self.write}: {len(value)} values do not fit in {target.count}"
                )
            return np.asarray(value)
        return value

    # ---- the protocol
    async def _start(self) -> None:
        assert self._loop is not None
        for pv in self._links.values():
            fanout(pv, self._loop).add(self)

    async def _info(self) -> ChannelInfo:
        read = self._infos.get(self.read, {})
        write = self._infos.get(self.write, {}) if self.write else {}
        return ChannelInfo(
            limits=write.get("limits", read.get("limits")),
            units=read.get("units", write.get("units")),
            precision=read.get("precision", write.get("precision")),
            choices=read.get("choices", write.get("choices")),
        )

    def _future(self) -> asyncio.Future[Any]:
        assert self._loop is not None
        fut = self._loop.create_future()
        self._pending.add(fut)
        fut.add_done_callback(self._pending.discard)
        return fut

    def _settle(
        self, fut: asyncio.Future[Any], result: Any, error: str, pv: str = ""
    ) -> None:
        """Settle a get's or put's future: ``error`` "" is done; ``put
        failed`` a ChannelError; anything else a DisconnectedError, naming
        ``pv`` (the PV asked: a put's write PV; the readback by default)."""
        if fut.done():
            return
        if error.startswith("put failed"):
            fut.set_exception(ChannelError(f"{self.write}: {error}"))
        elif error:
            fut.set_exception(DisconnectedError(f"{pv or self.read}: {error}"))
        else:
            fut.set_result(result)

    async def get(self) -> Reading:
        self.check_connected()
        fut = self._future()

        def answered(payload: Payload | None, error: str) -> None:
            self._on_loop(self._settle, fut, payload, error)

        self._links[self.read].get(answered)
        try:
            payload = await asyncio.wait_for(fut, GET_TIMEOUT)
        except TimeoutError:
            raise ChannelTimeoutError(
                f"{self.read}: no answer to a get within {GET_TIMEOUT} s"
            ) from None
        return self._convert(payload)

    async def _put(self, value: Any) -> None:
        assert self.write is not None
        converted = self._to_pv(value)
        fut = self._future()

        def done(_: Any, error: str) -> None:
            self._on_loop(self._settle, fut, None, error, self.write)

        try:
            self._links[self.write].put(converted, done)
        except ValueError as e:
            fut.cancel()
            raise ChannelError(f"{self.write}: cannot put {value!r}: {e}") from None
        await fut

    async def put_and_read(self, value: Any) -> Reading:
        """A put with completion, and the get of the readback sent from
        libca's thread the moment the put completes (no hop to the loop and
        back between them); the same errors as ``put`` then ``get``."""
        self._check_open()
        if self.write is None:
            raise ChannelError(f"{self.read} is a readback: it has no PV to put to")
        self.check_connected()
        converted = self._to_pv(value)
        fut = self._future()
        readback = self._links[self.read]

        def answered(payload: Payload | None, error: str) -> None:
            self._on_loop(self._settle, fut, payload, error)

        def done(_: Any, error: str) -> None:
            if error:
                self._on_loop(self._settle, fut, None, error, self.write)
            else:
                readback.get(answered)  # now, in libca's thread

        try:
            self._links[self.write].put(converted, done)
        except ValueError as e:
            fut.cancel()
            raise ChannelError(f"{self.write}: cannot put {value!r}: {e}") from None
        return self._convert(await fut)

    async def _close(self) -> None:
        self._fail_pending(DisconnectedError(f"{self.name}: closed"))
        if self._loop is None:
            return  # never started
        for pv in self._links.values():
            found = _fanouts.get((pv.name, self._loop))
            if found is not None:
                found.remove(self)


class PyepicsBackend(Backend):
    """Channel Access through pyepics (libca): one per process."""

    name = "pyepics"

    def __init__(self) -> None:
        self._channels: list[PyepicsChannel] = []

    def channel(
        self, read: str, write: str | None = None, *, default: Any = None
    ) -> Channel:
        made = PyepicsChannel(read, write, default)
        self._channels.append(made)
        return made

    def prefetch(self, names: Iterable[str]) -> None:
        """Start connecting (and subscribing to) the PVs ``names`` now, so
        the channels made for them later connect at once. A process whose
        blocks start one after another asks for all its PVs on the first
        (see ChannelPart); CA then searches for them all together."""
        for name in names:
            link(name).prefetch()

    async def close(self) -> None:
        channels, self._channels = self._channels, []
        for made in channels:
            await made.close()

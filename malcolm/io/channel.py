"""The channel protocol: one small async interface every transport implements.

A :class:`Channel` is one value on some transport (a Channel Access PV pair,
a pvAccess field, a Zebra2 field), read from one name and written to another
(often the same). Parts use only this interface; a backend (see
:mod:`malcolm.io.backends`) makes channels for its transport. The in-memory
soft backend (:mod:`malcolm.io.soft`) is the first implementation.

What a channel promises:

- ``await connect(timeout)`` returns a :class:`ChannelInfo` (what the
  backend can tell: limits, units, precision, choices). If the channel is
  not connected within ``timeout`` seconds it raises
  :class:`ChannelTimeoutError`, and *goes on trying*: its connection
  watchers hear when it connects.
- ``await get()`` returns the current :class:`Reading` (value, alarm,
  timeStamp); ``await put(value, timeout)`` returns once the put has
  completed (a Channel Access put with callback). A put's timeout stops the
  wait, never the put (docs/embedding.md). ``await put_and_read(value)``
  is a put, then a get once it completed (a backend may send the get
  itself the moment the put completes).
- ``await current(timeout)`` is a get whose answer the subscription has
  caught up with: it returns once the subscribers were given that reading
  (or a newer one). A backend gives each event of a name to all its
  channels of that name on one loop in one loop callback, so by then every
  channel of the name on the loop (every attribute bound to it) holds it
  too. An action that waits for a PV the block also shows uses it.
- ``subscribe(callback)`` calls ``callback(reading)`` on every change, and
  first after every (re)connection; ``watch_connection(callback)`` calls
  ``callback(state, message)`` when the connection state changes. Both
  return a function that ends them.
- every callback runs on the asyncio loop that called ``connect``: a backend
  whose library calls back in its own threads hands the call to that loop
  with :meth:`Channel._publish` / :meth:`Channel._set_state`, which go
  through :func:`malcolm.core.threads.call_threadsafe` (docs/channels.md).
- ``await close()`` lets go of the transport; the channel is then CLOSED
  and every later call raises ChannelError.
"""

from __future__ import annotations

import asyncio
import enum
import logging
import math
import sys
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from malcolm.core import Alarm, MalcolmError, TimeStamp, WaitTimeoutError
from malcolm.core.threads import call_threadsafe

__all__ = [
    "Backend",
    "Channel",
    "ChannelClosedError",
    "ChannelError",
    "ChannelInfo",
    "ChannelTimeoutError",
    "ConnectionState",
    "DisconnectedError",
    "Reading",
]

log = logging.getLogger(__name__)


class ChannelError(MalcolmError):
    """A channel operation failed; the message names the channel."""


class DisconnectedError(ChannelError):
    """The channel is not connected (yet, or any more)."""


class ChannelClosedError(ChannelError):
    """The channel was closed."""


class ChannelTimeoutError(ChannelError, WaitTimeoutError):
    """A connect or put was not done within its timeout (and goes on)."""


class ConnectionState(enum.Enum):
    """Where a channel's connection is."""

    #: made; ``connect`` not called yet
    IDLE = "idle"
    #: ``connect`` called, not connected yet (the backend keeps trying)
    CONNECTING = "connecting"
    CONNECTED = "connected"
    #: was connected and lost it (the backend keeps trying)
    DISCONNECTED = "disconnected"
    #: ``close`` was called
    CLOSED = "closed"


@dataclass(frozen=True)
class Reading:
    """A value as a transport gives it, with its alarm and time."""

    value: Any
    alarm: Alarm = Alarm.ok
    timeStamp: TimeStamp = field(default_factory=TimeStamp.now)  # noqa: N815


@dataclass(frozen=True)
class ChannelInfo:
    """What a backend can tell about a channel when it connects.

    ``None`` means the backend does not know (a part keeps what its
    definition says). A Channel Access backend fills these from the PV's
    control information (DRVL/DRVH or the display limits, EGU, PREC, the
    enum strings).
    """

    limits: tuple[float, float] | None = None
    units: str | None = None
    precision: int | None = None
    choices: tuple[str, ...] | None = None
    writeable: bool | None = None


ValueCallback = Callable[[Reading], None]
ConnectionCallback = Callable[[ConnectionState, str], None]


class Channel(ABC):
    """One value on a transport: read from ``read``, written to ``write``.

    Backends implement ``_start``, ``_info``, ``get``, ``_put`` and
    ``_close``, and report what happens with ``_publish`` (a new reading)
    and ``_set_state`` (the connection changed), from any thread.
    """

    def __init__(self, read: str, write: str | None = None) -> None:
        self.read = read
        self.write = write
        self._state = ConnectionState.IDLE
        self._message = ""
        self._loop: asyncio.AbstractEventLoop | None = None
        self._subscribers: list[ValueCallback] = []
        self._watchers: list[ConnectionCallback] = []
        self._waiters: list[asyncio.Future[None]] = []
        #: the last reading given to the subscribers while connected
        self._latest: Reading | None = None
        #: ``current`` calls waiting for the subscription to catch up
        self._catching_up: list[tuple[Reading, asyncio.Future[None]]] = []

    @property
    def name(self) -> str:
        """The channel's names, as messages give them."""
        if self.write is None or self.write == self.read:
            return self.read
        return f"{self.write} (readback {self.read})"

    @property
    def state(self) -> ConnectionState:
        return self._state

    @property
    def message(self) -> str:
        """Why the channel is not connected ("" when it is)."""
        return self._message

    # ---- the protocol
    async def connect(self, timeout: float | None = None) -> ChannelInfo:
        """Connect; returns what the backend can tell about the channel.

        Raises ChannelTimeoutError after ``timeout`` seconds; the channel
        goes on trying and its watchers hear when it connects.
        """
        self._check_open()
        loop = asyncio.get_running_loop()
        if self._loop is not None and self._loop is not loop:
            raise ChannelError(f"{self.name}: connected on another loop")
        self._loop = loop
        if self._state is ConnectionState.IDLE:
            self._state = ConnectionState.CONNECTING
            self._message = "not connected yet"
            await self._start()
        if self._state is not ConnectionState.CONNECTED:
            waiter: asyncio.Future[None] = loop.create_future()
            self._waiters.append(waiter)
            await _wait(
                waiter,
                timeout,
                lambda: (
                    f"{self.name}: not connected within {timeout} s"
                    f" ({self._message}); still trying"
                ),
                self._waiters,
                waiter,
            )
        return await self._info()

    @abstractmethod
    async def _start(self) -> None:
        """Begin connecting; call ``_set_state(CONNECTED)`` once connected, and
        go on trying (also after a loss) until closed."""

    @abstractmethod
    async def _info(self) -> ChannelInfo:
        """What the backend can tell about the connected channel."""

    @abstractmethod
    async def get(self) -> Reading:
        """The current reading; DisconnectedError if not connected."""

    @property
    def latest(self) -> Reading | None:
        """The last reading the subscribers were given (None when not
        connected)."""
        return self._latest

    async def current(self, timeout: float | None = None) -> Reading:
        """The reading now (a ``get``), once the subscribers have been given it.

        A get's answer may overtake the monitor events of the changes before
        it (Channel Access sends them from different queues), so what follows
        the subscription can still show an older value when ``get`` returns.
        This gets, then waits until the subscribers were given a reading with
        the got value and alarm, or a later timeStamp, and returns the latest
        they were given. Every channel of the same name on this loop was given
        it in the same loop callback (backends deliver so), so every attribute
        bound to the name shows it too. After ``timeout`` seconds raises
        ChannelTimeoutError; DisconnectedError if the connection is lost.
        """
        target = await self.get()
        latest = self._latest
        if latest is None or not caught_up(latest, target):
            assert self._loop is not None
            waiter: asyncio.Future[None] = self._loop.create_future()
            entry = (target, waiter)
            self._catching_up.append(entry)
            await _wait(
                waiter,
                timeout,
                lambda: (
                    f"{self.read}: no monitor event brought {target.value!r}"
                    f" (what a get read) within {timeout} s"
                ),
                self._catching_up,
                entry,
            )
        latest = self._latest
        if latest is None:  # lost since it caught up
            self.check_connected()
            return target
        return latest

    async def put(self, value: Any, timeout: float | None = None) -> None:
        """Write ``value`` and wait until the put has completed.

        After ``timeout`` seconds raises ChannelTimeoutError; the put goes
        on. DisconnectedError if not connected, ChannelError if the channel
        has no name to write to.
        """
        self._check_open()
        if self.write is None:
            raise ChannelError(f"{self.read} is a readback: it has no PV to put to")
        self.check_connected()
        putting = asyncio.ensure_future(self._put(value))
        try:
            await asyncio.wait_for(asyncio.shield(putting), timeout)
        except TimeoutError:
            putting.add_done_callback(_retrieve)
            raise ChannelTimeoutError(
                f"{self.write}: put of {value!r} not complete within {timeout} s;"
                " it goes on"
            ) from None
        except asyncio.CancelledError:
            putting.cancel()  # the caller was cancelled (abort): so is the wait
            raise

    @abstractmethod
    async def _put(self, value: Any) -> None:
        """Write ``value``; return when the put has completed."""

    async def put_and_read(self, value: Any) -> Reading:
        """Put ``value`` with completion, then read: the reading of ``read``
        (the readback) once the put has completed, as ``put`` then ``get``
        give it, with their errors. A backend may send the read the moment
        the put completes (the pyepics one does, from libca's thread, with
        no hop to the loop and back between)."""
        await self.put(value)
        return await self.get()

    def subscribe(self, callback: ValueCallback) -> Callable[[], None]:
        """``callback(reading)`` on every change; returns the unsubscribe."""
        self._check_open()
        self._subscribers.append(callback)
        return lambda: _discard(self._subscribers, callback)

    def watch_connection(self, callback: ConnectionCallback) -> Callable[[], None]:
        """``callback(state, message)`` on every connection change."""
        self._check_open()
        self._watchers.append(callback)
        return lambda: _discard(self._watchers, callback)

    async def close(self) -> None:
        """Let go of the transport; later calls raise ChannelClosedError."""
        if self._state is ConnectionState.CLOSED:
            return
        self._state = ConnectionState.CLOSED
        self._message = "closed"
        self._subscribers.clear()
        self._watchers.clear()
        self._latest = None
        for waiter in self._waiters:
            if not waiter.done():
                waiter.set_exception(
                    ChannelClosedError(f"{self.name}: closed while connecting")
                )
        self._stop_catching_up(ChannelClosedError(f"{self.name}: closed"))
        await self._close()

    @abstractmethod
    async def _close(self) -> None:
        """Let go of the transport (the base class has dropped the callbacks)."""

    # ---- for backends: report what happened, from any thread
    def _publish(self, reading: Reading) -> None:
        """Give ``reading`` to the subscribers, on the loop."""
        self._on_loop(self._deliver, reading)

    def _set_state(self, state: ConnectionState, message: str = "") -> None:
        """Record a connection change and tell the watchers, on the loop."""
        self._on_loop(self._change_state, state, message)

    def _on_loop(self, func: Callable[..., None], *args: Any) -> None:
        loop = self._loop
        if loop is None or loop.is_closed():
            return  # not connected on a loop (yet, or any more): nobody listens
        call_threadsafe(loop, func, *args)

    def _deliver(self, reading: Reading) -> None:
        """Give ``reading`` to the subscribers (on the loop). Backends call
        this for every channel of one name in the same loop callback."""
        if self._state is ConnectionState.CONNECTED:
            self._latest = reading
            for target, waiter in self._catching_up:
                if not waiter.done() and caught_up(reading, target):
                    waiter.set_result(None)
        for callback in list(self._subscribers):
            try:
                callback(reading)
            except Exception:
                log.exception("%s: subscriber %r raised", self.name, callback)

    def _change_state(self, state: ConnectionState, message: str) -> None:
        if self._state is ConnectionState.CLOSED:
            return
        if state is self._state:
            if state is not ConnectionState.CONNECTED:
                self._message = message  # a newer reason, nothing new to tell
            return
        self._state = state
        self._message = "" if state is ConnectionState.CONNECTED else message
        if state is not ConnectionState.CONNECTED:
            self._latest = None
            self._stop_catching_up(DisconnectedError(f"{self.name}: {message}"))
        if state is ConnectionState.CONNECTED:
            for waiter in self._waiters:
                if not waiter.done():
                    waiter.set_result(None)
        for callback in list(self._watchers):
            try:
                callback(state, self._message)
            except Exception:
                log.exception("%s: connection watcher %r raised", self.name, callback)

    def _stop_catching_up(self, error: ChannelError) -> None:
        for _, waiter in self._catching_up:
            if not waiter.done():
                waiter.set_exception(error)

    # ---- checks
    def _check_open(self) -> None:
        if self._state is ConnectionState.CLOSED:
            raise ChannelClosedError(f"{self.name}: the channel is closed")

    def check_connected(self) -> None:
        """Raise DisconnectedError (naming the channel and why) unless connected."""
        self._check_open()
        if self._state is not ConnectionState.CONNECTED:
            raise DisconnectedError(f"{self.name}: {self._message or 'not connected'}")

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name} {self._state.value}>"


class Backend(ABC):
    """Makes the channels of one transport for one process."""

    #: the name configuration chooses it by (``{"ca": "soft"}``)
    name = ""

    @abstractmethod
    def channel(
        self, read: str, write: str | None = None, *, default: Any = None
    ) -> Channel:
        """A channel read from ``read`` and written to ``write`` (not connected).

        ``default`` is the value a backend without hardware starts with (the
        soft backend); backends that read real values ignore it.
        """

    @abstractmethod
    async def close(self) -> None:
        """Close every channel this backend made (the process is stopping)."""


def caught_up(seen: Reading, target: Reading) -> bool:
    """Whether ``seen`` (given to subscribers) is as new as ``target`` (a
    get's answer): the same value and alarm, or a later timeStamp."""
    later, earlier = seen.timeStamp, target.timeStamp
    if (later.secondsPastEpoch, later.nanoseconds) > (
        earlier.secondsPastEpoch,
        earlier.nanoseconds,
    ):
        return True
    return seen.alarm == target.alarm and same_value(seen.value, target.value)


def same_value(a: Any, b: Any) -> bool:
    """``a == b`` for readings' values (arrays element by element, NaN is NaN)."""
    np = sys.modules.get("numpy")  # no array exists unless numpy is loaded
    if np is not None and (isinstance(a, np.ndarray) or isinstance(b, np.ndarray)):
        try:
            return bool(np.array_equal(a, b, equal_nan=True))
        except TypeError:  # not numbers: equal_nan does not apply
            return bool(np.array_equal(a, b))
    if isinstance(a, float) and isinstance(b, float):
        return a == b or (math.isnan(a) and math.isnan(b))
    try:
        return bool(a == b)
    except Exception:
        return False


async def _wait(
    waiter: asyncio.Future[None],
    timeout: float | None,
    why: Callable[[], str],
    waiting: list[Any],
    entry: Any,
) -> None:
    """Wait for ``waiter`` at most ``timeout`` s (ChannelTimeoutError saying
    ``why()`` after), then take ``entry`` off the list ``waiting``."""
    try:
        await asyncio.wait_for(waiter, timeout)
    except TimeoutError:
        raise ChannelTimeoutError(why()) from None
    finally:
        _discard(waiting, entry)


def _discard(items: list[Any], item: Any) -> None:
    if item in items:
        items.remove(item)


def _retrieve(fut: asyncio.Future[Any]) -> None:
    """Report the error of a put nobody waits for any more (its timeout expired)."""
    if not fut.cancelled() and fut.exception() is not None:
        log.warning("a put that outlived its timeout failed: %s", fut.exception())

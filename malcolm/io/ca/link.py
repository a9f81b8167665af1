"""One Channel Access PV of this Python process, over pyepics' libca.

A :class:`Link` is shared by every channel (of any backend, any process in
this interpreter) that names its PV: pyepics keeps one channel id per PV
name and context, so malcolm does too. It owns the PV's two subscriptions,
made when the PV first connects and kept (CA re-installs them after a
reconnection and sends their first events again):

- values: the TIME form, ``DBE_VALUE | DBE_ALARM`` (value, alarm, time);
- control information: the CTRL form, ``DBE_PROPERTY`` (limits, units,
  precision, enum strings), sent once on connection and when they change.

What happens arrives in libca's own threads and goes, unconverted, to the
link's listeners (:class:`LinkListener`), which hand it to their asyncio
loop. Gets and puts are asynchronous too (``ca_array_get_callback`` and a put
with callback): nothing here blocks waiting for the IOC. A get or put made on
a running loop is sent by :func:`flush_soon`, once at the end of the loop's
turn with every other request of that turn (a few packets where there was a
``ca_flush_io`` each). libca sends one circuit's requests in the order they
were made and the IOC serves them in that order, so a get made after a put
still reads what the put left.

Every libca call uses pyepics' one initial context, attached to whatever
thread calls (``ca.use_initial_context``), so CA has one context per
process whichever thread connects first.
"""

from __future__ import annotations

import asyncio
import ctypes
import threading
from collections.abc import Callable
from typing import Any, Protocol

import numpy as np
from epics import ca, dbr

__all__ = ["Link", "LinkListener", "flush_soon", "link"]

#: what a get or an event gives: (value, metadata) or an error message
Payload = tuple[Any, dict[str, Any]]
GetCallback = Callable[[Payload | None, str], None]

_VALUE_MASK = dbr.DBE_VALUE | dbr.DBE_ALARM


class LinkListener(Protocol):
    """What a link tells a channel, from libca's threads."""

    def link_connection(self, link: Link, up: bool) -> None: ...

    def link_value(self, link: Link, payload: Payload) -> None: ...

    def link_info(self, link: Link, payload: Payload) -> None: ...


def _context() -> None:
    """Make libca usable from this thread (pyepics' one initial context)."""
    if ca.libca is None:
        ca.initialize_libca()
    ca.use_initial_context()


#: the TIME forms of one number (most events): a pointer to their struct
_TIME_NUMBERS = {
    ftype: ctypes.POINTER(dbr.Map[ftype])
    for ftype in (dbr.TIME_DOUBLE, dbr.TIME_FLOAT, dbr.TIME_LONG, dbr.TIME_INT,
                  dbr.TIME_ENUM)
}  # fmt: skip


def _unpack(args: Any) -> Payload | None:
    """The value and metadata of a libca event (a get or a monitor).

    One number in its TIME form (most events) is read from its struct at
    once, giving what pyepics' unpacking gives (:func:`_unpack_any`, which
    takes the rest) in a fraction of the time, in libca's thread."""
    if args.count == 1:
        pointer = _TIME_NUMBERS.get(args.type)
        if pointer is not None and args.raw_dbr:
            event = ctypes.cast(args.raw_dbr, pointer).contents
            stamp = event.stamp
            return event.value, {
                "status": event.status,
                "severity": event.severity,
                "timestamp": dbr.make_unixtime(stamp),
                "posixseconds": stamp.secs + dbr.EPICS2UNIX_EPOCH,
                "nanoseconds": stamp.nsec,
            }
    return _unpack_any(args)


def _unpack_any(args: Any) -> Payload | None:
    """The value and metadata of any libca event, by pyepics' unpacking."""
    raw = dbr.cast_args(args)
    if raw[1] is None:
        return None
    try:
        metadata = ca._unpack_metadata(ftype=args.type, dbr_value=raw[0])
    except IndexError:  # an empty waveform
        metadata = {}
    value = ca._unpack(args.chid, raw, count=args.count, ftype=args.type)
    if isinstance(value, ctypes.Array):  # a one-element waveform
        value = np.array(value)
    return value, metadata


def _on_event(args: Any) -> None:
    if args.status != dbr.ECA_NORMAL:
        return  # a lost connection is told by the connection callback
    handler = args.usr
    payload = _unpack(args)
    if payload is not None and callable(handler):
        handler(payload)


#: callbacks of gets in flight: kept alive until libca calls them
_pending_gets: dict[int, ctypes.py_object] = {}
_pending_lock = threading.Lock()


def _on_get(args: Any) -> None:
    with _pending_lock:
        holder = _pending_gets.pop(id(args.usr), None)
    callback = args.usr
    if not callable(callback):
        return
    if args.status != dbr.ECA_NORMAL:
        callback(None, ca.message(args.status))
        return
    payload = _unpack(args)
    callback(payload, "" if payload is not None else "unreadable value")
    del holder


_flush_lock = threading.Lock()
_flush_loops: set[asyncio.AbstractEventLoop] = set()


def _flush() -> None:
    _context()
    ca.libca.ca_flush_io()


def flush_soon() -> None:
    """Send what libca has queued: once, at the end of this turn of the
    running asyncio loop (so a thousand gets go in a few packets), or now
    if no loop runs in this thread."""
    try:
        loop = asyncio.get_running_loop()
    except RuntimeError:
        _flush()
        return
    with _flush_lock:
        if loop in _flush_loops:
            return
        _flush_loops.add(loop)

    def flush() -> None:
        with _flush_lock:
            _flush_loops.discard(loop)
        _flush()

    loop.call_soon(flush)


_CB_EVENT = dbr.make_callback(_on_event, dbr.event_handler_args)
_CB_GET = dbr.make_callback(_on_get, dbr.event_handler_args)


class Link:
    """One PV: its channel id, subscriptions and the channels listening."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.connected = False
        #: native DBR type and element count, known once connected
        self.ftype: int | None = None
        self.count = 1
        self._chid: Any = None
        self._lock = threading.Lock()
        self._listeners: list[LinkListener] = []
        self._subscriptions: list[tuple[ctypes.py_object, Any]] = []
        self._value: Payload | None = None
        self._info: Payload | None = None
        #: subscribe once connected even with no listener (prefetch)
        self._wanted = False

    # ---- listeners (any thread)
    def prefetch(self) -> None:
        """Connect and subscribe now, before any channel listens, keeping
        the last value and control information to give the first listener
        at once (a process connects many blocks one after another)."""
        _context()
        with self._lock:
            self._wanted = True
            first = self._chid is None
            if not first and self.connected and not self._subscriptions:
                self._subscribe()
        if first:
            self._create()

    def _create(self) -> None:
        # pyepics keeps one chid per name: this calls back at once if the PV
        # is connected already (made by another library user)
        chid = ca.create_channel(
            self.name, connect=False, auto_cb=False, callback=self._on_connection
        )
        with self._lock:
            if self._chid is None:
                self._chid = chid
        flush_soon()

    def attach(self, listener: LinkListener) -> None:
        """Start telling ``listener``; connects the PV on first use. If the
        PV is connected already, tells what it knows at once."""
        _context()
        with self._lock:
            self._listeners.append(listener)
            first = self._chid is None
            connected, value, info = self.connected, self._value, self._info
            if connected and not self._subscriptions:
                self._subscribe()
                value = info = None  # the new subscriptions send them
        if first:
            self._create()
            return
        if connected:
            listener.link_connection(self, True)
            if info is not None:
                listener.link_info(self, info)
            if value is not None:
                listener.link_value(self, value)

    def detach(self, listener: LinkListener) -> None:
        """Stop telling ``listener``; the last one out ends the subscriptions."""
        with self._lock:
            if listener in self._listeners:
                self._listeners.remove(listener)
            if self._listeners or not self._subscriptions:
                return
            subscriptions, self._subscriptions = self._subscriptions, []
            self._value = self._info = None
            self._wanted = False
        _context()
        for _, evid in subscriptions:
            ca.libca.ca_clear_subscription(evid)
        flush_soon()

    def _tell(self) -> list[LinkListener]:
        with self._lock:
            return list(self._listeners)

    # ---- libca's callbacks (its threads)
    def _on_connection(self, pvname: str = "", chid: Any = None, conn: bool = False):
        with self._lock:
            if chid is not None and self._chid is None:
                self._chid = dbr.chid_t(chid)
            self.connected = bool(conn)
            if conn:
                self.ftype = ca.field_type(self._chid)
                self.count = ca.element_count(self._chid)
                wanted = self._listeners or self._wanted
                if wanted and not self._subscriptions:
                    self._subscribe()
            else:
                self._value = self._info = None
        for listener in self._tell():
            listener.link_connection(self, bool(conn))

    def _subscribe(self) -> None:
        """Subscribe to values and control information (holding the lock)."""
        assert self.ftype is not None
        for use_time, use_ctrl, mask, handler in (
            (False, True, dbr.DBE_PROPERTY, self._on_info),
            (True, False, _VALUE_MASK, self._on_value),
        ):
            ftype = ca.promote_fieldtype(self.ftype, use_time, use_ctrl)
            uarg = ctypes.py_object(handler)
            evid = ctypes.c_void_p()
            status = ca.libca.ca_create_subscription(
                ftype, 0, self._chid, mask, _CB_EVENT, uarg, ctypes.byref(evid)
            )
            if status == dbr.ECA_NORMAL:
                self._subscriptions.append((uarg, evid))
        ca.libca.ca_flush_io()

    def _on_value(self, payload: Payload) -> None:
        with self._lock:
            self._value = payload
        for listener in self._tell():
            listener.link_value(self, payload)

    def _on_info(self, payload: Payload) -> None:
        with self._lock:
            self._info = payload
        for listener in self._tell():
            listener.link_info(self, payload)

    # ---- gets and puts (any thread; they return at once)
    def get(self, callback: GetCallback) -> None:
        """Read the PV from the IOC (not the last monitor); ``callback``
        gets ``(payload, "")`` or ``(None, why)`` in libca's thread."""
        _context()
        with self._lock:
            chid, ftype, connected = self._chid, self.ftype, self.connected
        if not connected or ftype is None:
            callback(None, "not connected")
            return
        uarg = ctypes.py_object(callback)
        with _pending_lock:
            _pending_gets[id(callback)] = uarg
        status = ca.libca.ca_array_get_callback(
            ca.promote_fieldtype(ftype, True, False), 0, chid, _CB_GET, uarg
        )
        if status != dbr.ECA_NORMAL:
            with _pending_lock:
                _pending_gets.pop(id(callback), None)
            callback(None, ca.message(status))
            return
        flush_soon()

    def put(self, value: Any, callback: GetCallback) -> None:
        """Put ``value`` with a callback (``ca_array_put_callback``):
        ``callback(None, "")`` in libca's thread once the IOC has processed
        it, ``callback(None, why)`` if it failed. Raises ValueError for a
        value the PV cannot take (nothing is sent)."""
        _context()
        with self._lock:
            chid, ftype, count = self._chid, self.ftype, self.count
            connected = self.connected
        if not connected or ftype is None:
            callback(None, "not connected")
            return
        data, n = _marshal(value, ftype, count)
        uarg = ctypes.py_object(callback)
        with _pending_lock:
            _pending_puts[id(callback)] = uarg
        status = ca.libca.ca_array_put_callback(ftype, n, chid, data, _CB_PUT, uarg)
        if status != dbr.ECA_NORMAL:  # refused before it was sent
            with _pending_lock:
                _pending_puts.pop(id(callback), None)
            callback(None, put_error(status))
            return
        flush_soon()


def _marshal(value: Any, ftype: int, count: int) -> tuple[Any, int]:
    """``value`` as a ctypes array of the PV's native type, and its length.

    Arrays are converted whole by numpy and copied into the ctypes array in
    one go (a 65,536-byte text waveform or a 20,001-point trajectory went
    element by element through Python lists: milliseconds a put)."""
    if ftype == dbr.STRING:
        data = (1 * dbr.Map[dbr.STRING])()
        data[0].value = str(value).encode("utf-8")[:39]
        return data, 1
    kind = type(value)
    if (kind is float or kind is int or kind is bool) and _LOW <= value <= _HIGH:
        return _marshal_scalar(value, ftype), 1
    values = np.atleast_1d(np.asarray(value))
    if values.ndim != 1 or values.dtype.kind not in "biuf":
        raise ValueError(f"{value!r} is not a number or an array of numbers")
    n = min(len(values), count) or 1
    ctype = dbr.Map[ftype]
    native = np.dtype(ctype)
    part = values[:n]
    if native.kind in "iu" and part.dtype.kind == "f":
        if not np.all(np.equal(np.mod(part, 1), 0)):
            raise ValueError(f"{value!r} is not whole for an integer PV")
        part = part.astype(np.int64)
    data = (n * ctype)()
    if len(part):
        # wraps out-of-range integers as ctypes' own assignment did
        converted = np.ascontiguousarray(part.astype(native, copy=False))
        ctypes.memmove(data, converted.ctypes.data, converted.nbytes)
    return data, n


#: the Python numbers :func:`_marshal_scalar` takes (what numpy makes an
#: int64 or a float64 of; NaN and the infinities go numpy's way)
_LOW, _HIGH = -(2**63), 2**63 - 1
#: per native type: its ctypes array of one, whether it holds whole numbers
_SCALARS: dict[int, tuple[Any, bool]] = {}


def _marshal_scalar(value: float, ftype: int) -> Any:
    """A Python number as a ctypes array of one of the PV's native type: what
    :func:`_marshal`'s numpy path gives, built by ctypes alone (a scalar
    put through numpy took about 9 us here)."""
    known = _SCALARS.get(ftype)
    if known is None:
        ctype = dbr.Map[ftype]
        known = _SCALARS[ftype] = (1 * ctype, np.dtype(ctype).kind in "iu")
    array, whole = known
    if whole and type(value) is float:
        if not value.is_integer():
            raise ValueError(f"{value!r} is not whole for an integer PV")
        value = int(value)
    data = array()
    data[0] = value  # ctypes wraps an out-of-range integer as numpy does
    return data


#: callbacks of puts in flight: kept alive until libca calls them
_pending_puts: dict[int, ctypes.py_object] = {}

#: libca's status for a put cut off by the loss of its circuit (caerr.h's
#: ECA_DISCONN): the IOC went away, the value was not refused
ECA_DISCONN = 192

#: how a put's error starts when its circuit was lost under it
PUT_DISCONNECTED = "disconnected during the put"


def put_error(status: int) -> str:
    """What a put's callback is told of libca's ``status``, in its
    completion or when ``ca_array_put_callback`` refuses it at once: "" if
    it completed; the lost circuit (ECA_DISCONN: libca may know before the
    connection callback says so) as :data:`PUT_DISCONNECTED`; anything
    else (no write access...) as ``put failed``."""
    if status == dbr.ECA_NORMAL:
        return ""
    if status == ECA_DISCONN:
        return f"{PUT_DISCONNECTED}: {ca.message(status)}"
    return f"put failed: {ca.message(status)}"


def _on_put(args: Any) -> None:
    with _pending_lock:
        holder = _pending_puts.pop(id(args.usr), None)
    callback = args.usr
    if callable(callback):
        callback(None, put_error(args.status))
    del holder


_CB_PUT = dbr.make_callback(_on_put, dbr.event_handler_args)


_links: dict[str, Link] = {}
_links_lock = threading.Lock()


def link(name: str) -> Link:
    """The process's one link to PV ``name``."""
    with _links_lock:
        found = _links.get(name)
        if found is None:
            found = _links[name] = Link(name)
        return found

"""Serve every block of a Process over pvAccess (interop.md §2), on p4p.

``await start_pva_server(process, port)`` returns a :class:`PvaServer`
(``await server.close()`` stops it). Channels are made when a client asks
for them: ``<mri>`` (the whole block) and ``<mri>.<field>`` (one field, or
``meta``). Each is a p4p ``SharedPV`` fed by one ``process.subscribe`` of
its path: the first monitor update is the whole structure, each later
delta of the process becomes exactly one update carrying only the fields
it changed. A change of shape (a field added or removed, a meta whose
value type differs) reopens the channel with the new type; a block or
field that goes away closes it. Channels nobody is connected to are let go.

p4p calls this module from its own threads: name look-ups only read, and
every put, method call and channel opening is handed to the process's loop
with ``Process.call_threadsafe`` (docs/channels.md). Errors go back to the
client as ``"<ExceptionType>: <message>"`` and change nothing.
"""

from __future__ import annotations

import asyncio
import copy
import logging
import os
import threading
from collections.abc import Sequence
from typing import Any

from p4p import Value
from p4p.server import DynamicProvider, Server
from p4p.server.raw import SharedPV
from p4p.server.raw import _SharedPV as _RawSharedPV

from malcolm.core import (
    BadValueError,
    NotFoundError,
    Process,
    apply_changes,
    call_threadsafe,
)

from .convert import STRUCTURE, assign, fits, spec_at, to_dict, to_value, type_spec
from .errlog import route_errlog
from .ops import LoopSharedPV, OpRunner, error_text
from .results import method_args, result_value, version_tag
from .setters import Setter, compile_setter

__all__ = ["PvaServer", "start_pva_server"]

log = logging.getLogger(__name__)

# SharedPV.post without p4p's wrap step (the identity here: no nt)
_post = _RawSharedPV.post

# a put's changed set that is a field's value alone; what to_dict and
# _plain_put give back as it is
_VALUE = {"value"}
_SCALARS = frozenset({float, int, str, bool})

#: seconds a channel nobody is connected to is kept (a client reconnecting)
RELEASE_DELAY = 2.0


class _Channel:
    """One served name: a SharedPV kept in step with its path in the process."""

    def __init__(self, server: PvaServer, name: str, path: list[str]) -> None:
        self.server = server
        self.name = name
        self.path = path  # [mri] or [mri, field]
        self.pv, self.handler = server._shared_pv(name)
        self.handler.chan = self
        self.clients = 0
        self.made = 0  # makeChannel calls, to tell a release is stale
        self._data: Any = None
        # fast-path changes not yet applied to _data: path -> latest data,
        # in the order of each path's latest change (see the data property)
        self._pending: dict[tuple[str, ...], Any] = {}
        self.spec: Any = None
        self.type: Any = None
        # the Value each update is built in, reused (see _next_update)
        self._update: Value | None = None
        self.sub: Any = None
        self.closed = False
        # change path (relative to the block) -> its compiled setter and the
        # path relative to the channel, for self.spec (reset with it)
        self._setters: dict[tuple[str, ...], tuple[Setter, tuple[str, ...]]] = {}
        # leaf -> what the setters last set it to, to leave it unmarked when
        # it is set to that again (malcolm.io.pva.setters); cleared whenever
        # the PV's value is set another way
        self._last: dict[str, Any] = {}
        # the block meta and a meta channel go whole: never the fast path
        self._fast_ok = self.path[1:] != ["meta"]
        self._block = len(self.path) == 1  # the whole block's channel
        self._skip = len(self.path) - 1  # what begins a block's path of it

    @property
    def data(self) -> Any:
        """The channel's copy of its path's data, current (the changes the
        fast path only recorded are applied first)."""
        if self._pending:
            pending = [[list(k), v] for k, v in self._pending.items()]
            self._pending.clear()
            self._data = _apply_changes(self._data, pending)
        return self._data

    @data.setter
    def data(self, data: Any) -> None:
        self._pending.clear()
        self._data = data

    def prime(self) -> None:
        """Open the PV at once with a snapshot of its path (in p4p's thread:
        a client never waits on a PV not yet open); :meth:`open`'s
        subscription then corrects it, on the loop, if it changed."""
        for _ in range(5):
            try:
                data = copy.deepcopy(self.server.process.get(self.path))
                break
            except RuntimeError:  # changed on the loop while read: again
                continue
        else:
            return
        self.data = self._tagged(data)
        self.spec = type_spec(self.data)
        value = to_value(self.data)
        self.type = value.type()
        self._update = None
        self._last.clear()
        self.pv.open(value)

    def _next_update(self) -> Value:
        """The Value to build the next update in: one per channel, its marks
        cleared. A post copies only the marked fields into the PV's current
        value and clones the Value for each subscriber, so the same Value
        serves every update; a new one for each would allocate the whole
        structure (a block's: every field of every attribute) per change."""
        value = self._update
        if value is None:
            value = self._update = Value(self.type)
        else:
            value.unmark()
        return value

    # ---- on the loop
    def open(self) -> None:
        if self.closed:
            return
        try:
            self.sub = self.server.process.subscribe(
                self.path, self._on_changes, below=self._on_below
            )
        except NotFoundError:  # gone between the look-up and now
            self.server._forget(self)

    def _tagged(self, data: Any) -> Any:
        """``data`` with the version tag in the block meta's tags."""
        if not isinstance(data, dict):
            return data
        meta = data if self.path[1:] == ["meta"] else None
        if len(self.path) == 1:
            meta = data.get("meta")
        if isinstance(meta, dict):
            tags = list(meta.get("tags") or [])
            if not any(str(t).startswith("version:") for t in tags):
                if meta is not data:  # maybe the process's own: a copy
                    data["meta"] = meta = dict(meta)
                meta["tags"] = [*tags, version_tag()]
        return data

    def _meta_changed(self, changes: list[list[Any]]) -> bool:
        if self.path[1:] == ["meta"]:
            return True
        return len(self.path) == 1 and any(c[0][:1] == ["meta"] for c in changes)

    def _on_changes(self, changes: list[list[Any]]) -> None:
        """Changes relative to the channel's path (the first, the whole of
        it; then what :meth:`_on_below` does not get)."""
        try:
            if self.closed:
                return
            self._apply(changes)
        except Exception as e:  # a monitor must never stop the process
            log.exception("pva %s: %s", self.name, error_text(e))

    def _on_below(self, changes: list[list[Any]]) -> None:
        """Changes lying below the channel's path, as the block gave them
        (paths relative to the block: a field channel's begin with its
        field; shared with other subscribers, so never changed here)."""
        try:
            if self.closed:
                return
            if self._fast_ok and self._data is not None and self._apply_fast(changes):
                return
            skip = self._skip
            self._apply([[list(c[0][skip:]), *c[1:]] for c in changes])
        except Exception as e:  # a monitor must never stop the process
            log.exception("pva %s: %s", self.name, error_text(e))

    def _apply(self, changes: list[list[Any]]) -> None:
        if self.closed:
            return
        self._last.clear()  # the PV's value is set here without the setters
        if self.data is None or any(not c[0] and len(c) == 2 for c in changes):
            if changes[-1] == [[]]:
                self.server._forget(self)
                return
            before = self.data
            # a copy: its dicts may be ones the process gave (never changed)
            own = copy.deepcopy(before) if before is not None else None
            self.data = self._tagged(apply_changes(own, changes))
            if before is not None and self.pv.isOpen():
                if self.data == before:
                    return  # the snapshot opened with was already current
                spec = type_spec(self.data)
                if spec == self.spec:
                    value = self._next_update()
                    assign_all(value, self.data, spec)
                    self.pv.post(value)
                    return
            self._reopen()
            return
        if any(len(c) == 1 and not c[0] for c in changes):
            self.server._forget(self)  # the block or field was deleted
            return
        self.data = _apply_changes(self.data, changes)
        if self._meta_changed(changes):
            self._tagged(self.data)
        posted: list[tuple[list[str], Any, Any]] = []
        reshape = False
        for change in changes:
            path = list(change[0])
            if self.path[1:] == ["meta"] or (
                len(self.path) == 1 and path[:1] == ["meta"]
            ):
                # the meta (and its version tag) goes whole
                path = [] if self.path[1:] == ["meta"] else ["meta"]
            sub_spec = spec_at(self.spec, path) if len(change) == 2 else None
            if sub_spec is None:
                reshape = True
                break
            data = _at(self.data, path)
            if isinstance(sub_spec, tuple) and not fits(sub_spec, data):
                reshape = True  # a structure of another shape: a new type?
                break
            posted.append((path, data, sub_spec))
        if reshape:
            spec = type_spec(self.data)
            if spec != self.spec:
                self._reopen(spec)
                return
            posted = [([], self.data, spec)]
        value = self._next_update()
        for path, data, sub_spec in posted:
            if path:
                assign(value, path, data, sub_spec)
            else:
                assign_all(value, data, sub_spec)
        self.pv.post(value)

    def _apply_fast(self, changes: list[list[Any]]) -> bool:
        """Post ``changes`` (paths relative to the block, see
        :meth:`_on_below`) if each sets a field whose type it still fits (the
        common case: a value, its alarm and timeStamp); False, with nothing
        posted, for anything else (the block's meta, a new shape), which
        :meth:`_apply` does in full."""
        value = self._update  # self._next_update(), in line
        if value is None:
            value = self._update = Value(self.type)
        else:
            value.unmark()
        setters = self._setters
        # each change's data is recorded, applied to data when it is next
        # read: a path's latest change moved last, so applying them in order
        # gives what applying every change in turn would. One recorded before
        # a change that does not fit is harmless: _apply then applies the
        # recorded ones and every change again, which gives the same data
        pending = self._pending
        try:
            for path, data in changes:  # a deletion ([path]) does not unpack
                known = setters.get(tuple(path))
                if known is None:
                    known = self._setter(path)
                    if known is None:
                        return False
                setter, where = known
                if not setter(value, data):
                    return False
                pending.pop(where, None)
                pending[where] = data
        except ValueError:  # (or a setter's: _apply then does it in full)
            return False
        _post(self.pv, value)
        return True

    def _setter(self, path: list[str]) -> tuple[Setter, tuple[str, ...]] | None:
        """The compiled setter of a change at ``path`` (relative to the
        block) and the path it sets relative to the channel; None if that is
        not a field of the channel's type (or the block's meta)."""
        where = tuple(path[self._skip :])
        if self._block and where[:1] == ("meta",):
            return None  # the block meta (and its version tag) goes whole
        sub_spec = spec_at(self.spec, where)
        if sub_spec is None:
            return None
        setter = compile_setter(sub_spec, ".".join(where), last=self._last)
        known = self._setters[tuple(path)] = (setter, where)
        return known

    def _reopen(self, spec: Any = None) -> None:
        self._setters.clear()
        self._last.clear()
        self.spec = spec or type_spec(self.data)
        value = to_value(self.data)
        self.type = value.type()
        self._update = None
        if self.pv.isOpen():
            self.pv.close()
        self.pv.open(value)

    def release(self, made: int) -> None:
        """Let go of the channel if nobody connected to it since ``made``."""
        self.server._forget(self, made)

    def close(self, keep: bool = False) -> None:
        """Stop following the process; ``keep``: close the PV for reuse (a
        release), else destroy it (the name is gone or the server stops)."""
        self.closed = True
        if self.sub is not None:
            self.server.process.unsubscribe(self.sub)
            self.sub = None
        self.handler.chan = None
        if keep:
            self.pv.close()
            self.server._keep_pv(self.name, self.pv, self.handler)
        else:
            self.pv.close(destroy=True)

    # ---- p4p handler (called in p4p's threads)
    def onFirstConnect(self, pv: SharedPV) -> None:
        self.clients = 1

    def onLastDisconnect(self, pv: SharedPV) -> None:
        self.clients = 0
        self.server._schedule_release(self)

    # ---- operations, on the loop (LoopSharedPV hands them there)
    def put(self, pv: SharedPV, op: Any) -> None:
        self.server._ops.start(op, self._put(op))

    def rpc(self, pv: SharedPV, op: Any) -> None:
        self.server._ops.start(op, self._rpc(op))

    async def _put(self, op: Any) -> None:
        value = op.value()
        mri = self.path[0]
        changed = value.changedSet()
        if changed == _VALUE and len(self.path) == 2:  # a field's value: most
            new = value["value"]
            if type(new) not in _SCALARS:
                new = _plain_put(to_dict(new))
            await self.server.process.put(self.path, new)
            op.done()
            return
        puts: dict[str, Any] = {}  # field -> new value, in the order given
        for dotted in sorted(changed):
            parts = dotted.split(".")
            if len(self.path) == 2:
                field, rest, prefix = self.path[1], parts, ""
            else:
                field, rest, prefix = parts[0], parts[1:], f"{parts[0]}."
            if rest[:1] != ["value"]:
                raise BadValueError(
                    f"{mri}.{'.'.join([field, *rest])}: only a value can be put"
                )
            if field not in puts:
                puts[field] = _plain_put(to_dict(value[f"{prefix}value"]))
        if not puts:
            raise BadValueError(f"{self.name}: a put must set a value")
        for field, new in puts.items():
            await self.server.process.put([mri, field], new)
        op.done()

    async def _rpc(self, op: Any) -> None:
        mri, method, args = method_args(self.path, op.value(), op.pvRequest)
        process = self.server.process
        result = await process.post([mri, method], args)
        op.done(result_value(result, self._returns(mri, method)))

    def _current(self, path: tuple[str, ...]) -> Any:
        """The channel's data, current at ``path``: the changes the fast path
        recorded are applied first only if one of them is at, above or below
        ``path`` (a call's took and returned leave its returns as they are,
        and are not applied for every call)."""
        first = path[0]
        for key in self._pending:
            if key[0] == first:  # (most differ there: a call's took, returned)
                n = min(len(key), len(path))
                if key[:n] == path[:n]:
                    return self.data
        return self._data

    def _returns(self, mri: str, method: str) -> Any:
        """The method's ``returns`` meta: from this channel's copy if it
        holds the method (kept current on the loop), else from the process."""
        try:
            if self.path == [mri, method]:
                return self._current(("meta", "returns"))["meta"]["returns"]
            if self.path == [mri]:
                where = (method, "meta", "returns")
                return self._current(where)[method]["meta"]["returns"]
        except (KeyError, TypeError):
            pass
        return self.server.process.get([mri, method, "meta", "returns"])


class _Handler:
    """A SharedPV's handler: forwards to the channel now using the PV."""

    def __init__(self) -> None:
        self.chan: _Channel | None = None

    def onFirstConnect(self, pv: SharedPV) -> None:  # noqa: N802 (p4p's name)
        if self.chan is not None:
            self.chan.onFirstConnect(pv)

    def onLastDisconnect(self, pv: SharedPV) -> None:  # noqa: N802
        if self.chan is not None:
            self.chan.onLastDisconnect(pv)

    def put(self, pv: SharedPV, op: Any) -> None:
        if self.chan is None:
            op.done(error="NotFoundError: the channel is closed")
        else:
            self.chan.put(pv, op)

    def rpc(self, pv: SharedPV, op: Any) -> None:
        if self.chan is None:
            op.done(error="NotFoundError: the channel is closed")
        else:
            self.chan.rpc(pv, op)


def _apply_changes(data: Any, changes: list[list[Any]]) -> Any:
    """:func:`malcolm.core.apply_changes` for changes below the root, without
    copying what a change brings: each dict on a change's path is copied
    before it is changed, so a value kept as the process gave it (and gave
    every other subscriber) is never changed in place. ``data``, the
    channel's own, is changed in place."""
    for change in changes:
        *parents, last = change[0]
        target = data
        for key in parents:
            target[key] = target = dict(target[key])
        if len(change) == 1:
            del target[last]
        else:
            target[last] = change[1]
    return data


def _at(data: Any, path: Sequence[str]) -> Any:
    for key in path:
        data = data[key]
    return data


def assign_all(value: Value, data: Any, spec: Any) -> None:
    """Every field of ``data`` set in ``value`` (a whole new structure)."""
    for key, sub in spec[2]:
        if isinstance(data, dict) and key in data and data[key] is not None:
            assign(value, [key], data[key], sub)


def _plain_put(new: Any) -> Any:
    """A put's value as the block takes it (a table's columns without id)."""
    if isinstance(new, dict) and new.get("typeid", STRUCTURE) != STRUCTURE:
        new = {k: v for k, v in new.items() if k != "typeid"}
    return new


class _Names:
    """p4p's DynamicProvider handler: which names exist, and their channels."""

    def __init__(self, server: PvaServer) -> None:
        self.server = server

    def testChannel(self, name: str) -> Any:
        try:
            if self.server._path_of(name) is not None:
                return True
        except Exception as e:  # a look-up must never stop the server
            log.debug("pva search %r: %s", name, error_text(e))
        # not cached as missing: a block made later is found at once
        return DynamicProvider.NotYet

    def makeChannel(self, name: str, peer: str) -> Any:
        try:
            return self.server._channel(name)
        except Exception as e:
            log.debug("pva channel %r: %s", name, error_text(e))
            return None


class PvaServer:
    """A pvAccess server for every block of ``process`` (see the module doc)."""

    def __init__(
        self, process: Process, port: int = 5075, conf: dict[str, str] | None = None
    ) -> None:
        self.process = process
        self.port = port
        self.conf = dict(conf or {})
        self._lock = threading.Lock()
        self._channels: dict[str, _Channel] = {}
        # closed SharedPVs of released channels, by name, for reuse: p4p does
        # not give back all of a destroyed SharedPV's memory, so a name that
        # is let go and asked for again would grow the server each time
        self._kept: dict[str, tuple[SharedPV, _Handler]] = {}
        self._provider: DynamicProvider | None = None
        self._server: Server | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        # puts and calls: run on the loop; those waiting in _tasks
        self._ops = OpRunner()
        self._tasks: set[asyncio.Task[Any]] = self._ops.tasks

    @property
    def address(self) -> str:
        """``host:port`` the server listens on (its TCP port)."""
        if self._server is None:
            return f"0.0.0.0:{self.port}"
        conf = self._server.conf()
        port = conf.get("EPICS_PVAS_SERVER_PORT", str(self.port))
        hosts = conf.get("EPICS_PVAS_INTF_ADDR_LIST", "").split() or ["0.0.0.0"]
        return f"{hosts[0].split(':')[0]}:{port}"

    def start(self) -> None:
        """Listen (on the process's loop thread, before or after it starts)."""
        self._loop = asyncio.get_running_loop()
        route_errlog()
        # the environment's EPICS_PVA* settings, but always this port
        conf = {k: v for k, v in os.environ.items() if k.startswith("EPICS_PVA")}
        conf["EPICS_PVAS_SERVER_PORT"] = str(self.port)
        conf.update(self.conf)
        self._provider = DynamicProvider(f"malcolm-{id(self)}", _Names(self))
        try:
            self._server = Server(providers=[self._provider], conf=conf, useenv=False)
        except RuntimeError as e:
            raise RuntimeError(
                f"pvAccess port {self.port}: {e} (--pva-port 0 serves no pvAccess)"
            ) from None

    async def close(self) -> None:
        """Stop serving: every client is disconnected."""
        server, self._server = self._server, None
        if server is not None:
            server.stop()
        with self._lock:
            channels = list(self._channels.values())
            self._channels.clear()
            kept = [pv for pv, _ in self._kept.values()]
            self._kept.clear()
        for chan in channels:
            chan.close()
        for pv in kept:
            pv.close(destroy=True)
        self._ops.close()

    # ---- names (any thread)
    def _path_of(self, name: str) -> list[str] | None:
        mris = self._mris()
        if name in mris:
            return [name]
        mri, dot, field = name.rpartition(".")
        if dot and mri in mris:
            block = self.process.get_block(mri)
            if field == "meta" or field in block:
                return [mri, field]
        return None

    def _mris(self) -> list[str]:
        for _ in range(3):
            try:
                return self.process.mris
            except RuntimeError:  # the dict changed while copied: again
                continue
        return []

    def _channel(self, name: str) -> SharedPV | None:
        path = self._path_of(name)
        if path is None:
            return None
        with self._lock:
            chan = self._channels.get(name)
            if chan is None:
                chan = _Channel(self, name, path)
                chan.prime()
                self._channels[name] = chan
                self._call(chan.open)
            chan.made += 1
            return chan.pv

    def _shared_pv(self, name: str) -> tuple[SharedPV, _Handler]:
        """The kept PV of ``name`` (under the lock), or a new one."""
        kept = self._kept.pop(name, None)
        if kept is not None:
            return kept
        handler = _Handler()
        assert self._loop is not None
        return LoopSharedPV(self._loop, handler), handler

    def _keep_pv(self, name: str, pv: SharedPV, handler: _Handler) -> None:
        with self._lock:
            if self._server is not None and name not in self._kept:
                self._kept[name] = (pv, handler)
                return
        pv.close(destroy=True)

    def _schedule_release(self, chan: _Channel) -> None:
        made = chan.made
        loop = self._loop
        if loop is not None and not loop.is_closed():
            loop.call_soon_threadsafe(
                loop.call_later, RELEASE_DELAY, chan.release, made
            )

    def _forget(self, chan: _Channel, made: int | None = None) -> None:
        """Drop ``chan``; with ``made`` (a release), only if it is still
        unused since then (checked under the lock makeChannel takes, so no
        client gets it), keeping its PV for the next channel of that name."""
        with self._lock:
            if made is not None and (chan.clients or chan.made != made):
                return
            if self._channels.get(chan.name) is chan:
                del self._channels[chan.name]
        chan.close(keep=made is not None and self._server is not None)

    def _call(self, func: Any, *args: Any) -> Any:
        if self._loop is None:
            raise RuntimeError("the pvAccess server has not started")
        return call_threadsafe(self._loop, func, *args)

    @property
    def channel_names(self) -> list[str]:
        """The names that have a channel now (for tests and diagnostics)."""
        with self._lock:
            return list(self._channels)


async def start_pva_server(
    process: Process, port: int = 5075, conf: dict[str, str] | None = None
) -> PvaServer:
    """Serve every block of ``process`` on ``port`` (0: any free port); call on
    the loop the process runs (or will run) on. ``conf`` adds p4p server
    settings (``EPICS_PVAS_*``)."""
    server = PvaServer(process, port, conf)
    server.start()
    return server

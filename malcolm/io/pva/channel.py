"""One served pvAccess name, kept in step with its path in the process.

A :class:`_Channel` is one p4p ``SharedPV`` fed by one
``process.subscribe`` of its path (``[mri]`` or ``[mri, field]``): opened
with a snapshot of the path, then each change the process publishes is
exactly one update carrying only the fields it changed (the fast path:
setters compiled once per field, :mod:`malcolm.io.pva.setters`). A change
of shape reopens the PV with the new type; a deletion closes the channel.
Its puts and calls are :class:`~malcolm.io.pva.channel_requests.ChannelRequests`'.
:class:`_Handler` is the PV's handler, forwarding to the channel using it
(a released channel's PV is kept and reused by the next of its name).
"""

from __future__ import annotations

import copy
import logging
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from p4p import Value
from p4p.server.raw import SharedPV
from p4p.server.raw import _SharedPV as _RawSharedPV

from malcolm.core import NotFoundError, apply_changes
from malcolm.core.fields import plain_changes

from .channel_requests import ChannelRequests
from .convert import assign, fits, spec_at, to_value, type_spec
from .log_pair import LogPair, compile_log_pair
from .ops import error_text
from .results import version_tag
from .setters import Setter, compile_setter

if TYPE_CHECKING:
    from .server import PvaServer

log = logging.getLogger(__name__)

# SharedPV.post without p4p's wrap step (the identity here: no nt)
_post = _RawSharedPV.post


class _Channel(ChannelRequests):
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
        self._memo: list[Any] = []  # result_value's (ChannelRequests._rpc)
        # method name -> its took and returned's pair function for self.spec
        # (malcolm.io.pva.log_pair; False: none), reset with the setters
        self._pairs: dict[str, Any] = {}
        self._skip = len(self.path) - 1  # what begins a block's path of it

    @property
    def data(self) -> Any:
        """The channel's copy of its path's data, current (the changes the
        fast path only recorded are applied first)."""
        if self._pending:
            # (a MethodLog the fast path took as it is becomes its plain data)
            pending = plain_changes([[list(k), v] for k, v in self._pending.items()])
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
        self._setters.clear()
        self._pairs.clear()
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
                self.path, self._on_changes, below=self._on_below, logs=self._on_logs
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
            changes = plain_changes(changes)  # (a MethodLog as plain data)
            self._apply([[list(c[0][skip:]), *c[1:]] for c in changes])
        except Exception as e:  # a monitor must never stop the process
            log.exception("pva %s: %s", self.name, error_text(e))

    def _on_logs(self, changes: list[list[Any]]) -> None:
        """A call's took and returned, one batch (``Process.subscribe``'s
        ``logs``: ``[[[name, "took"], took], [[name, "returned"],
        returned]]``): set by the method's pair function
        (:mod:`malcolm.io.pva.log_pair`) and posted; anything it does not
        take goes as :meth:`_on_below` would take it."""
        try:
            if self.closed:
                return
            pair = self._pairs.get(changes[0][0][0])
            if pair is None and self._data is not None:
                name = changes[0][0][0]
                pair = self._pairs[name] = self._log_pair(name)
            if pair:  # (made once the channel has its data)
                value = self._update  # self._next_update(), in line
                if value is None:
                    value = self._update = Value(self.type)
                else:
                    value.unmark()
                try:
                    if pair(value, changes):
                        _post(self.pv, value)
                        return
                except (AttributeError, TypeError, ValueError):
                    pass  # (not the core's logs: as _on_below takes them)
                self._last.clear()  # (leaves it set, not posted)
            self._on_below(changes)
        except Exception as e:  # a monitor must never stop the process
            log.exception("pva %s: %s", self.name, error_text(e))

    def _log_pair(self, name: str) -> LogPair | bool:
        """Method ``name``'s pair function for this channel's type, or
        False if it has none (the block meta's channel, another shape)."""
        if not self._fast_ok:
            return False
        skip = self._skip
        took = (name, "took")[skip:]
        returned = (name, "returned")[skip:]
        took_spec = spec_at(self.spec, took)
        returned_spec = spec_at(self.spec, returned)
        if took_spec is None or returned_spec is None:
            return False
        pair = compile_log_pair(
            (took_spec, took), (returned_spec, returned), self._last, self._pending
        )
        return pair or False

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
                try:  # moved last (there after its path's first change)
                    del pending[where]
                except KeyError:
                    pass
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
        self._pairs.clear()
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
        chan = self.chan
        if chan is None:
            op.done(error="NotFoundError: the channel is closed")
        else:  # chan.rpc(pv, op), in line: once per call
            chan.server._ops.start(op, chan._rpc(op))


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

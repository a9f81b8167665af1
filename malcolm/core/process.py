"""Process: hosts controllers, finds blocks by mri, publishes changes as deltas."""

from __future__ import annotations

import asyncio
import concurrent.futures
import logging
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

from .block import Block
from .errors import NotFoundError
from .fields import Change, plain_changes
from .threads import LoopOwner, call_threadsafe

if TYPE_CHECKING:
    from malcolm.controllers.base import Controller

log = logging.getLogger(__name__)

Callback = Callable[[Any], None]


class Subscription:
    """A subscriber's path and callback; ``delta`` selects deltas or whole values."""

    def __init__(
        self,
        path: Sequence[str],
        callback: Callback,
        delta: bool,
        below: Callback | None = None,
        logs: Callback | None = None,
    ) -> None:
        self.path = list(path)
        #: the path below the mri, which the changes of a block are relative to
        self.rest = self.path[1:]
        self.callback = callback
        self.delta = delta
        #: gets the block's own changes lying below the path (see subscribe)
        self.below = below
        #: gets a call's took and returned batch (see subscribe): ``logs``
        #: if given, else ``below``
        self.logs = logs or below
        #: the field subscribed to, for a path [mri, field] (else None)
        self.field: str | None = self.rest[0] if len(self.rest) == 1 else None
        self.active = True

    def __repr__(self) -> str:
        return f"<Subscription {'.'.join(self.path)} delta={self.delta}>"


def _below(rest: list[str], changes: list[Change]) -> list[Change] | None:
    """The changes lying strictly below ``rest`` (a path in a block), as they
    are; None if one of them is at ``rest`` or above it (see subscribe's
    ``below``)."""
    if not rest:  # the whole block: every change, unless one replaces it
        for change in changes:
            if not change[0]:
                return None
        return changes
    n = len(rest)
    if n == 1:  # a field (the common case)
        name = rest[0]
        touching = []
        for change in changes:
            path = change[0]
            if not path:
                return None
            if path[0] == name:
                if len(path) == 1:
                    return None
                touching.append(change)
        return touching
    touching = []
    for change in changes:
        path = list(change[0])
        if path[:n] == rest:
            if len(path) == n:
                return None
            touching.append(change)
        elif rest[: len(path)] == path:
            return None  # a parent replaced or deleted
    return touching


def _index(data: Any, path: Sequence[str], where: str) -> Any:
    for i, key in enumerate(path):
        if isinstance(data, dict) and key in data:
            data = data[key]
        else:
            raise NotFoundError(f"{where}: no {'.'.join(path[: i + 1])!r}")
    return data


class Process:
    """A set of blocks served together, with one asyncio loop owning their state.

    Every change a block makes is delivered to the subscribers of any path
    it touches, as a list of ``[path, value]`` changes relative to the
    subscribed path (``[[], value]`` replaces it whole). Once started, the
    loop ``start()`` ran on owns the blocks: other threads reach it through
    :meth:`call_threadsafe` (see :mod:`malcolm.core.threads`).

    ``channels`` chooses a channel backend per transport, e.g.
    ``{"ca": "soft"}`` (see :mod:`malcolm.io` and docs/channels.md).
    """

    def __init__(
        self,
        name: str = "malcolm",
        designs_dir: str | None = None,
        channels: Mapping[str, str] | None = None,
    ) -> None:
        self.name = name
        #: where managers keep their designs (``<designs_dir>/<mri>/``)
        self.designs_dir = designs_dir
        #: transport -> name of the channel backend chosen for it
        self.channels: dict[str, str] = dict(channels or {})
        #: transport -> the backend object in use (made by malcolm.io)
        self.backends: dict[str, Any] = {}
        #: the loop that owns the blocks' state, once started
        self.owner: LoopOwner | None = None
        self._controllers: dict[str, Controller] = {}
        self._subs: dict[str, list[Subscription]] = {}
        # deliveries wait here while a callback runs, so that every
        # subscriber sees changes in the order they were made
        # (subscription, payload, the callback of it that gets the payload)
        self._queue: deque[tuple[Subscription, Any, Callback]] = deque()
        self._delivering = False
        # a call's took kept back (see hold): (mri, change, the returned's path)
        self._held: tuple[str, Change, list[str]] | None = None
        self._hosting_watchers: list[Callable[[], None]] = []
        self.loop: asyncio.AbstractEventLoop | None = None
        self.started = False

    # ---- hosting
    def add_controller(self, controller: Controller) -> None:
        """Host ``controller``'s block (once started: on the loop's thread)."""
        owner = self.owner
        if owner is not None and not owner.here():
            what = f"the blocks of process {self.name!r}"
            if owner.elsewhere(what, self.add_controller, controller)[0]:
                return
        mri = controller.mri
        if mri in self._controllers:
            raise ValueError(f"a block with mri {mri!r} already exists in {self.name}")
        self._controllers[mri] = controller
        controller.process = self
        controller.block.set_listener(self._on_changes)
        controller.block.owner = self.owner
        self._hosting_changed()

    def remove_controller(self, mri: str) -> Controller:
        """Stop hosting ``mri``'s block (stop the controller first if it runs).

        The block is found no more; each subscriber of one of its paths gets
        the change ``[[]]`` (deleted; None with ``delta=False``), then nothing.
        """
        owner = self.owner
        if owner is not None and not owner.here():
            what = f"the blocks of process {self.name!r}"
            done, controller = owner.elsewhere(what, self.remove_controller, mri)
            if done:
                return controller
        controller = self.get_controller(mri)
        del self._controllers[mri]
        controller.block.set_listener(None)
        for sub in self._subs.pop(mri, []):
            # nothing is queued for it after this: it is off the list
            self._queue.append((sub, [[[]]] if sub.delta else None, sub.callback))
        self._flush()
        self._hosting_changed()
        return controller

    def watch_hosting(self, callback: Callable[[], None]) -> Callable[[], None]:
        """Call ``callback()`` after each block added or removed (where
        :meth:`add_controller`/:meth:`remove_controller` run: on the loop once
        started); returns a function that stops watching."""
        self._hosting_watchers.append(callback)

        def unwatch() -> None:
            if callback in self._hosting_watchers:
                self._hosting_watchers.remove(callback)

        return unwatch

    def _hosting_changed(self) -> None:
        for callback in list(self._hosting_watchers):
            try:
                callback()
            except Exception:
                log.exception("hosting watcher %r raised", callback)

    @property
    def mris(self) -> list[str]:
        return list(self._controllers)

    def get_controller(self, mri: str) -> Controller:
        try:
            return self._controllers[mri]
        except KeyError:
            known = ", ".join(self._controllers) or "none"
            raise NotFoundError(f"no block {mri!r} (blocks: {known})") from None

    def get_block(self, mri: str) -> Block:
        return self.get_controller(mri).block

    async def start(self) -> None:
        """Bind to the running loop and bring every controller to its ready state.

        From here on the loop's thread owns every block's state.
        """
        self.loop = asyncio.get_running_loop()
        self.owner = LoopOwner(self.loop, self.name)
        for controller in self._controllers.values():
            controller.block.owner = self.owner
        self.started = True
        for controller in list(self._controllers.values()):
            try:
                await controller.start()
            except Exception as e:  # one block must not stop the others
                log.error(
                    "%s did not start: %s: %s", controller.mri, type(e).__name__, e
                )
                controller.health.set_value(f"did not start: {type(e).__name__}: {e}")

    async def stop(self) -> None:
        """Stop every controller, then close the channel backends in use."""
        for controller in list(self._controllers.values()):
            await controller.stop()
        for transport, backend in list(self.backends.items()):
            try:
                await backend.close()
            except Exception as e:  # one backend must not stop the others
                log.error(
                    "%s backend did not close: %s: %s", transport, type(e).__name__, e
                )
        self.started = False

    def call_threadsafe(
        self, func: Callable[..., Any], *args: Any
    ) -> concurrent.futures.Future[Any]:
        """Run ``func(*args)`` on the process's loop, from any thread.

        The one path from library and worker threads to block state (see
        :func:`malcolm.core.threads.call_threadsafe`): returns a future of
        the result; ``.result()`` waits for it (never on the loop thread).
        """
        if self.loop is None or self.loop.is_closed():
            raise RuntimeError(f"process {self.name!r} has not been started")
        return call_threadsafe(self.loop, func, *args)

    # ---- reading and writing by path
    def get(self, path: Sequence[str]) -> Any:
        """The plain data at a path such as ``["COUNTER", "counter", "value"]``."""
        if not path:
            raise NotFoundError("empty path")
        block = self.get_block(path[0])
        if len(path) == 1:
            return block.to_dict()
        if path[1] == "meta":
            return _index(block.meta.to_dict(), path[2:], path[0])
        fld = block[path[1]]
        return _index(fld.to_dict(), path[2:], f"{path[0]}.{path[1]}")

    async def put(self, path: Sequence[str], value: Any) -> None:
        """Put to ``[mri, attribute]`` or ``[mri, attribute, "value"]``."""
        if len(path) == 2:  # the common case, as _field_path would give it
            mri, name = path
        else:
            mri, name = self._field_path(path, "put")
        controller = self._controllers.get(mri) or self.get_controller(mri)
        await controller.put(name, value)

    async def post(self, path: Sequence[str], params: dict[str, Any] | None = None):
        """Call a method at ``[mri, method]``; returns what it returns."""
        if len(path) == 2:  # the common case, as _field_path would give it
            mri, name = path
        else:
            mri, name = self._field_path(path, "post")
        controller = self._controllers.get(mri) or self.get_controller(mri)
        return await controller.call(name, params or {})

    @staticmethod
    def _field_path(path: Sequence[str], what: str) -> tuple[str, str]:
        path = list(path)
        if len(path) == 3 and path[2] == "value" and what == "put":
            path = path[:2]
        if len(path) != 2:
            raise NotFoundError(f"{what} needs a path [mri, field], got {path}")
        return path[0], path[1]

    # ---- subscriptions
    def subscribe(
        self,
        path: Sequence[str],
        callback: Callback,
        delta: bool = True,
        below: Callback | None = None,
        logs: Callback | None = None,
    ) -> Subscription:
        """Subscribe; the callback gets the current value at once, then changes.

        With ``delta=True`` the first call is ``[[[], value]]`` and later ones
        lists of changes relative to ``path``; with ``delta=False`` each call
        gets the whole value at ``path`` (None once it has been deleted).

        ``below`` (with ``delta``), if given, gets instead each batch whose
        changes that touch ``path`` all lie strictly below it, as the block
        gave them: paths relative to the block (``path`` without its mri
        begins each), neither copied nor filtered for a block's path (they
        are shared: read them, never change them). Any other batch (``path``
        itself or a parent replaced or deleted) goes to ``callback`` as
        without ``below``. (For a subscriber that follows every change of a
        field, such as a pvAccess channel: no copy of every change's path.)
        A method's took or returned reaches ``below`` as the block published
        it: the :class:`~malcolm.core.MethodLog` itself when its values are
        all scalars (see ``fields._new_log``); every other callback gets
        plain data (its ``to_dict()``).

        ``logs`` (with ``below``), if given, gets instead of ``below`` the
        one batch of a call's took and returned (a method that does not
        wait, see :meth:`hold`): always ``[[[name, "took"], took],
        [[name, "returned"], returned]]``, ``name`` the method's (the
        field subscribed to, or any method for a block's path), so that
        it can set both with no test of each change.
        """
        if isinstance(path, str) or not path:
            raise NotFoundError(f"subscribe needs a path [mri, ...], got {path!r}")
        owner = self.owner
        if owner is not None and not owner.here():
            what = f"the subscriptions of {'.'.join(map(str, path))}"
            done, sub = owner.elsewhere(
                what, self.subscribe, path, callback, delta, below, logs
            )
            if done:
                return sub
        value = self.get(path)
        if delta and below is not None:
            sub = Subscription(path, callback, delta, below, logs)
        else:
            sub = Subscription(path, callback, delta)
        self._subs.setdefault(sub.path[0], []).append(sub)
        self._deliver(sub, [[[], value]] if delta else value)
        return sub

    def unsubscribe(self, sub: Subscription) -> None:
        """Stop delivery to ``sub`` (including anything not yet delivered)."""
        owner = self.owner
        if owner is not None and not owner.here():
            what = f"the subscriptions of {'.'.join(map(str, sub.path))}"
            if owner.elsewhere(what, self.unsubscribe, sub)[0]:
                return
        sub.active = False
        subs = self._subs.get(sub.path[0], [])
        if sub in subs:
            subs.remove(sub)
            if not subs:
                del self._subs[sub.path[0]]

    def _deliver(self, sub: Subscription, payload: Any) -> None:
        try:
            sub.callback(payload)
        except Exception:
            log.exception("subscriber %r raised", sub)

    def _get_or_none(self, path: Sequence[str]) -> tuple[bool, Any]:
        try:
            return True, self.get(path)
        except NotFoundError:
            return False, None

    def _relative(self, sub: Subscription, changes: list[Change]) -> list[Change]:
        """``changes`` as seen from ``sub.path`` (empty if none touch it)."""
        rest = sub.rest
        if not rest:  # the whole block: every change, its path copied
            return [[list(c[0]), *c[1:]] for c in changes]
        if len(rest) == 1:  # a field (the common case): in one pass
            name = rest[0]
            try:
                return [[list(c[0][1:]), *c[1:]] for c in changes if c[0][0] == name]
            except IndexError:  # the whole block replaced or deleted: below
                pass
        n = len(rest)
        out: list[Change] = []
        for change in changes:
            p = change[0]
            if type(p) is not list:
                p = list(p)
            if p[:n] == rest:
                out.append([p[n:], *change[1:]])
            elif rest[: len(p)] == p:
                # a parent of the subscribed path was replaced or deleted
                exists, value = self._get_or_none(sub.path)
                out.append([[], value] if exists else [[]])
        return out

    def hold(self, mri: str, change: Change, until: list[str]) -> Any:
        """Publish ``change`` of block ``mri`` a little later: with the
        block's next change if that is the one change at ``until``, as one
        batch (``change`` first), else alone just before any other change of
        any block is published, or at :meth:`release`. So a call's took and
        returned, when its method does not wait, reach each subscriber as
        one batch, and nothing published meanwhile is seen before the took.
        On the loop; one change is held at a time (a new one releases it).
        Returns what :meth:`complete` takes to publish the change at
        ``until`` with it."""
        if self._held is not None:
            self.release()
        self._held = held = (mri, change, until)
        return held

    def complete(self, held: Any, change: Change) -> bool:
        """Publish ``change`` (the one at ``until`` of what :meth:`hold`
        gave ``held``) with the held change as one batch if that is still
        held (nothing was published meanwhile): what ``Block.notify`` and
        :meth:`_on_changes` would do with it (a call's returned, where it
        was made: ``Controller.call``). False, with nothing published, if
        it is not: the caller publishes ``change`` as the block's."""
        if self._held is held:
            self._held = None
            self._on_logs(held[0], [held[1], change], held[2][0])
            return True
        return False

    def release(self) -> None:
        """Publish the change :meth:`hold` keeps back, if any, now."""
        held = self._held
        if held is not None:
            self._held = None
            self._on_changes(held[0], [held[1]])

    def _on_changes(self, mri: str, changes: list[Change]) -> None:
        if self._held is not None:  # a call's took goes first (see hold)
            held = self._held
            self._held = None
            if held[0] == mri and len(changes) == 1 and changes[0][0] == held[2]:
                self._on_logs(mri, [held[1], changes[0]], held[2][0])
                return
            self._on_changes(held[0], [held[1]])
        subs = self._subs.get(mri)
        if not subs:
            return  # nothing queued: an outer _flush (if any) has the rest
        queue = self._queue
        # the changes as plain data, made for the first subscriber that is
        # not given them as they are (a method's log is published as a
        # MethodLog, see fields._new_log)
        plain: list[Change] | None = None
        # no copy of subs: nothing below changes them (callbacks run in _flush)
        for sub in subs:
            below = sub.below
            if below is not None:
                field = sub.field
                if field is not None:
                    # a field's subscriber (the common case), _below in line:
                    # changes all below the field go as they are, none: skip
                    hit = other = False
                    for change in changes:
                        path = change[0]
                        if not path:
                            break  # the block replaced or deleted
                        if path[0] == field:
                            if len(path) == 1:
                                break  # the field replaced or deleted
                            hit = True
                        else:
                            other = True
                    else:
                        if hit:
                            touching = _below(sub.rest, changes) if other else changes
                            queue.append((sub, touching, below))
                        continue
                elif not sub.rest:
                    # the whole block's (_below in line): every change, as it
                    # is, unless one replaces the block
                    for change in changes:
                        if not change[0]:
                            break
                    else:
                        queue.append((sub, changes, below))
                        continue
                else:
                    touching = _below(sub.rest, changes)
                    if touching is not None:
                        if touching:
                            queue.append((sub, touching, below))
                        continue
            if plain is None:
                plain = plain_changes(changes)
            self._queue_relative(sub, plain)
        self._flush()

    def _on_logs(self, mri: str, changes: list[Change], name: str) -> None:
        """:meth:`_on_changes` of a call's took and returned as one batch
        (``changes``, both below field ``name``, neither replacing it): a
        field's ``below`` subscriber gets them if it is ``name``'s, with no
        test of each change's path, a block's as they are; the others as
        :meth:`_on_changes` gives them."""
        subs = self._subs.get(mri)
        if not subs:
            return
        queue = self._queue
        plain: list[Change] | None = None  # (as in _on_changes)
        for sub in subs:
            below = sub.below
            if below is not None:
                field = sub.field
                if field is not None:
                    if field == name:
                        queue.append((sub, changes, sub.logs))
                    continue
                rest = sub.rest
                if not rest:  # a block's: the batch as it is
                    queue.append((sub, changes, sub.logs))
                    continue
                touching = _below(rest, changes)
                if touching is not None:  # (never None: nothing is replaced)
                    if touching:
                        queue.append((sub, touching, below))
                    continue
            if plain is None:
                plain = plain_changes(changes)
            self._queue_relative(sub, plain)
        self._flush()

    def _queue_relative(self, sub: Subscription, plain: list[Change]) -> None:
        """Queue ``sub``'s share of the plain ``changes`` (relative to its
        path, or its whole value when it takes no deltas), if any."""
        relative = self._relative(sub, plain)
        if relative:
            payload = relative if sub.delta else self._get_or_none(sub.path)[1]
            self._queue.append((sub, payload, sub.callback))

    def _flush(self) -> None:
        if self._delivering:
            return  # the outer _flush delivers these after what came before
        self._delivering = True
        queue = self._queue
        try:
            while queue:
                sub, payload, callback = queue.popleft()
                if sub.active:
                    try:  # _deliver, in line: once per subscriber per change
                        callback(payload)
                    except Exception:
                        log.exception("subscriber %r raised", sub)
        finally:
            self._delivering = False

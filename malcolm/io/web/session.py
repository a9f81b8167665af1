"""One WebSocket client's requests and subscriptions (interop.md §3)."""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable
from typing import Any

from malcolm.core import MalcolmError, Process, Subscription

from . import protocol as p
from .directory import directory_get

log = logging.getLogger(__name__)

#: messages queued for one client before it counts as stuck and is dropped
MAX_QUEUED = 20_000


def _retrieve(task: asyncio.Future[Any]) -> None:
    """Read a finished operation's outcome (whether or not anyone waits)."""
    if not task.cancelled():
        task.exception()


class Session:
    """Answers one connection's messages; ``send(text)`` queues a reply.

    Get and Subscribe are answered at once, in order; Put and Post run as
    tasks so that a long call (a scan's ``run``) does not hold up the
    connection. Every subscription ends when the session closes.
    """

    def __init__(self, process: Process, send: Callable[[str], None]) -> None:
        self.process = process
        self.send = send
        self.subs: dict[int, Subscription | None] = {}
        # subscriptions under "." watch the process's blocks come and go
        self.watches: dict[int, Callable[[], None]] = {}
        self.tasks: set[asyncio.Task[None]] = set()
        self.closed = False

    def handle(self, text: str | bytes) -> None:
        """Answer one message; an error is answered, never raised."""
        try:
            request = p.parse(text)
        except p.ProtocolError as e:
            self.send(p.error(e.id, p.error_text(e)))
            return
        try:
            if request.typeid == p.GET:
                self.send(p.return_(request.id, self._get(request.path)))
            elif request.typeid == p.SUBSCRIBE:
                self._subscribe(request)
            elif request.typeid == p.UNSUBSCRIBE:
                self._unsubscribe(request.id)
            else:
                task = asyncio.ensure_future(self._write(request))
                self.tasks.add(task)
                task.add_done_callback(self.tasks.discard)
        except MalcolmError as e:
            self.send(p.error(request.id, p.error_text(e)))
        except Exception as e:  # a bug must not end the connection
            log.exception("web request %s failed", request)
            self.send(p.error(request.id, p.error_text(e)))

    def _get(self, path: list[str]) -> Any:
        if path[0] == ".":
            return directory_get(self.process, path)
        return self.process.get(path)

    async def _write(self, request: p.Request) -> None:
        if request.typeid == p.PUT:
            operation = self.process.put(request.path, request.value)
        else:
            operation = self.process.post(request.path, request.parameters)
        # the operation is the process's: a client that goes (or a server
        # that closes) stops waiting for it, never the operation itself
        inner = asyncio.ensure_future(operation)
        inner.add_done_callback(_retrieve)
        try:
            value = await asyncio.shield(inner)
            reply = p.return_(request.id, value if request.typeid == p.POST else None)
        except asyncio.CancelledError:
            raise
        except MalcolmError as e:
            reply = p.error(request.id, p.error_text(e))
        except Exception as e:  # a part's bug: reported to the caller
            log.warning("web %s failed", request, exc_info=True)
            reply = p.error(request.id, p.error_text(e))
        if not self.closed:
            self.send(reply)

    def _subscribe(self, request: p.Request) -> None:
        id_ = request.id
        if id_ in self.subs:
            self.send(p.error(id_, f"BadValueError: subscription id {id_} is in use"))
            return
        if request.path[0] == ".":
            self._subscribe_directory(request)
            return

        def on_change(payload: Any) -> None:
            if request.delta:
                self.send(p.delta(id_, payload))
            else:
                self.send(p.update(id_, payload))

        self.subs[id_] = None  # taken before the first update arrives
        try:
            self.subs[id_] = self.process.subscribe(
                request.path, on_change, delta=request.delta
            )
        except BaseException:
            del self.subs[id_]
            raise

    def _subscribe_directory(self, request: p.Request) -> None:
        """A path under ``"."``: its value now, and again whenever a block is
        added or removed (the block list changes; a model of a block that
        goes away ends as NotFound), only when it differs from the last."""
        id_ = request.id
        path = list(request.path)
        value = directory_get(self.process, path)  # NotFoundError: refused
        last = [value]

        def send(new: Any) -> None:
            self.send(
                p.delta(id_, [[[], new]]) if request.delta else p.update(id_, new)
            )

        def on_hosting() -> None:
            if self.closed or id_ not in self.subs:
                return
            try:
                new = directory_get(self.process, path)
            except MalcolmError as e:
                self._end_watch(id_)
                self.send(p.error(id_, p.error_text(e)))
                return
            if new != last[0]:
                last[0] = new
                send(new)

        self.subs[id_] = None
        self.watches[id_] = self.process.watch_hosting(on_hosting)
        send(value)

    def _end_watch(self, id_: int) -> None:
        self.subs.pop(id_, None)
        unwatch = self.watches.pop(id_, None)
        if unwatch is not None:
            unwatch()

    def _unsubscribe(self, id_: int) -> None:
        if id_ not in self.subs:
            self.send(p.error(id_, f"NotFoundError: no subscription with id {id_}"))
            return
        sub = self.subs.pop(id_)
        if sub is not None:
            self.process.unsubscribe(sub)
        self._end_watch(id_)
        self.send(p.return_(id_))

    async def close(self) -> None:
        """End every subscription and wait for calls in flight to answer."""
        self.closed = True
        for sub in self.subs.values():
            if sub is not None:
                self.process.unsubscribe(sub)
        self.subs.clear()
        for unwatch in self.watches.values():
            unwatch()
        self.watches.clear()
        if self.tasks:
            await asyncio.gather(*self.tasks, return_exceptions=True)

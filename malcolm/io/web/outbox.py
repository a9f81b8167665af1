"""One WebSocket connection's outgoing messages, sent in order."""

from __future__ import annotations

import asyncio
from collections import deque
from collections.abc import Callable

from aiohttp import web

from . import session as session_module


class Outbox:
    """Messages for one client, written by one writer at a time, in order.

    The connection's reader writes the replies to what it has just handled
    itself (``inline`` while it handles, then ``await flush()``), so a Get's
    reply takes no hop through another task; anything sent otherwise (an
    update caused by someone else's put, the reply of a call that has
    finished) starts a writer task. More than ``session.MAX_QUEUED`` waiting
    messages mean the client is not reading: they are dropped and
    ``on_stuck()`` is called once.
    """

    def __init__(self, ws: web.WebSocketResponse, on_stuck: Callable[[], None]) -> None:
        self.ws = ws
        self.on_stuck = on_stuck
        self.messages: deque[str] = deque()
        #: the reader is handling a message and writes its replies itself
        self.inline = False
        self.writing = False
        self.writer: asyncio.Future[None] | None = None
        self.dead = False

    def send(self, text: str) -> None:
        if self.dead:
            return
        if len(self.messages) >= session_module.MAX_QUEUED:
            self.dead = True
            self.messages.clear()
            self.on_stuck()
            return
        self.messages.append(text)
        if not (self.inline or self.writing or self.writer):
            self.writer = asyncio.ensure_future(self._write_later())

    async def _write_later(self) -> None:
        try:
            await self.flush()
        finally:
            self.writer = None

    async def flush(self) -> None:
        """Send what waits (unless a writer is at it already)."""
        if self.writing:
            return
        self.writing = True
        try:
            while self.messages and not self.dead:
                text = self.messages.popleft()
                try:
                    await self.ws.send_str(text)
                except (ConnectionError, RuntimeError):  # the client went
                    self.dead = True
                    self.messages.clear()
        finally:
            self.writing = False

    async def close(self) -> None:
        """Send nothing more; wait for a write in progress to end."""
        self.dead = True
        self.messages.clear()
        if self.writer is not None:
            await self.writer

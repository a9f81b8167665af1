"""The HTTP + WebSocket server: ``/ws`` (the JSON protocol), ``/rest/`` and
the web GUI's files at ``/``."""

from __future__ import annotations

import asyncio
import logging
import socket
import weakref
from pathlib import Path

from aiohttp import WSCloseCode, WSMsgType, web

from malcolm.core import Process

from . import protocol as p
from .outbox import Outbox
from .rest import add_rest_routes
from .session import Session

log = logging.getLogger(__name__)

#: the web GUI's files (plain HTML, CSS and JavaScript modules)
STATIC = Path(__file__).resolve().parent / "static"

#: frames above this are refused by aiohttp itself (closing the connection);
#: below it, messages over protocol.MAX_MESSAGE get an Error
FRAME_LIMIT = 64 * p.MAX_MESSAGE


class WebServer:
    """A running server; ``url`` is where it listens, ``close()`` stops it."""

    def __init__(self, process: Process) -> None:
        self.process = process
        self.app = web.Application(client_max_size=p.MAX_MESSAGE)
        self.app.router.add_get("/ws", self._websocket)
        add_rest_routes(self.app, process)
        self.app.router.add_get("/", self._index)
        self.app.router.add_static("/static/", STATIC)
        self.runner = web.AppRunner(self.app, access_log=None, shutdown_timeout=1.0)
        self.sessions: weakref.WeakSet[Session] = weakref.WeakSet()
        self.host = ""
        self.port = 0

    @property
    def url(self) -> str:
        host = "localhost" if self.host in ("", "0.0.0.0", "::") else self.host
        return f"http://{host}:{self.port}/"

    async def start(self, port: int, host: str) -> None:
        await self.runner.setup()
        site = web.TCPSite(self.runner, host, port)
        await site.start()
        server = site._server  # aiohttp offers no public way to the bound port
        sockets = getattr(server, "sockets", None) or []
        self.host = host
        self.port = sockets[0].getsockname()[1] if sockets else port

    async def start_on(self, sock: socket.socket, host: str) -> None:
        """Serve on ``sock``, already bound and listening (:mod:`.lazy`)."""
        await self.runner.setup()
        await web.SockSite(self.runner, sock).start()
        self.host = host
        self.port = sock.getsockname()[1]

    async def close(self) -> None:
        """Stop listening, end every session and its subscriptions."""
        for session in list(self.sessions):
            for task in list(session.tasks):
                task.cancel()
        await self.runner.cleanup()

    async def _index(self, request: web.Request) -> web.StreamResponse:
        return web.FileResponse(STATIC / "index.html")

    async def _websocket(self, request: web.Request) -> web.WebSocketResponse:
        ws = web.WebSocketResponse(max_msg_size=FRAME_LIMIT, heartbeat=30)
        await ws.prepare(request)
        session: Session

        def stuck() -> None:
            # a client that does not read is dropped, not buffered forever
            log.warning("web client %s is not reading: dropped", request.remote)
            session.closed = True
            closing = asyncio.ensure_future(
                ws.close(code=WSCloseCode.POLICY_VIOLATION, message=b"not reading")
            )
            session.tasks.add(closing)
            closing.add_done_callback(session.tasks.discard)

        outbox = Outbox(ws, stuck)
        session = Session(self.process, outbox.send)
        self.sessions.add(session)
        try:
            async for msg in ws:
                if msg.type in (WSMsgType.TEXT, WSMsgType.BINARY):
                    outbox.inline = True
                    try:
                        session.handle(msg.data)
                    finally:
                        outbox.inline = False
                    await outbox.flush()
                if session.closed:
                    break
        finally:
            await session.close()
            await outbox.close()
            if not ws.closed:
                await ws.close()
        return ws


async def start_web_server(
    process: Process, port: int = 8008, host: str = "0.0.0.0"
) -> WebServer:
    """Serve ``process`` over HTTP and WebSocket on ``host:port`` (0: any free
    port); returns the server (``url``, ``async close()``)."""
    server = WebServer(process)
    await server.start(port, host)
    log.info("web server at %s", server.url)
    return server

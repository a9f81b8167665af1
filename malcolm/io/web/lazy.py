"""A web port that is bound at start but loads aiohttp when first used.

The web stack (aiohttp and what it imports) is about 13 MiB of a served
process and a tenth of a second of its start. A process that GDA drives over
pvAccess may never see a browser, so ``malcolm serve`` and ``malcolm demo``
bind and listen on the web port at once (its address is printed, a bad port
is reported) but import the server only when the first connection is
waiting. The import runs in a worker thread, so the loop keeps serving
meanwhile; the waiting connection stays in the socket's backlog and is the
first the aiohttp server accepts.
"""

from __future__ import annotations

import asyncio
import logging
import socket
from typing import TYPE_CHECKING

from malcolm.core import Process

if TYPE_CHECKING:
    from .server import WebServer

log = logging.getLogger(__name__)


def _load_server_module() -> None:
    from . import server  # noqa: F401  (imported for its side effect)


class LazyWebServer:
    """A listening web port whose server starts on its first connection.

    ``url`` is where it listens; ``server`` is the running
    :class:`~malcolm.io.web.server.WebServer` once a client came (else None);
    ``await started()`` starts it now; ``close()`` stops whichever is there.
    """

    def __init__(self, process: Process, port: int, host: str = "0.0.0.0") -> None:
        self.process = process
        self.sock = socket.create_server(
            (host, port), family=socket.AF_INET, backlog=128, reuse_port=False
        )
        self.sock.setblocking(False)
        self.host = host
        self.port = self.sock.getsockname()[1]
        self.server: WebServer | None = None
        self._loop = asyncio.get_running_loop()
        self._starting: asyncio.Task[WebServer] | None = None
        self._closed = False
        self._loop.add_reader(self.sock.fileno(), self._first_connection)

    @property
    def url(self) -> str:
        host = "localhost" if self.host in ("", "0.0.0.0", "::") else self.host
        return f"http://{host}:{self.port}/"

    def _first_connection(self) -> None:
        self.started().add_done_callback(self._report)

    def _report(self, task: asyncio.Future[WebServer]) -> None:
        if task.cancelled():
            return
        error = task.exception()
        if error is not None:
            log.error("web server could not start on %s: %s", self.url, error)

    def started(self) -> asyncio.Task[WebServer]:
        """Start the server on the bound socket (once); the task gives it."""
        if self._starting is None:
            self._loop.remove_reader(self.sock.fileno())
            self._starting = asyncio.ensure_future(self._start())
        return self._starting

    async def _start(self) -> WebServer:
        await asyncio.to_thread(_load_server_module)
        from .server import WebServer

        server = WebServer(self.process)
        await server.start_on(self.sock, self.host)
        self.server = server
        log.info("web server at %s", server.url)
        return server

    async def close(self) -> None:
        """Stop listening, and stop the server if one started."""
        if self._closed:
            return
        self._closed = True
        if self._starting is None:
            self._loop.remove_reader(self.sock.fileno())
            self.sock.close()
            return
        try:
            server = await self._starting
        except Exception:
            self.sock.close()
            return
        await server.close()

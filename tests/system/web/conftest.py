"""A demo process served on the web from a thread of its own, and a client.

The server's loop runs in a background thread (as in ``malcolm demo``, with
the loop guard on); tests talk to it over real TCP from their own loop.
"""

from __future__ import annotations

import asyncio
import json
import os
import shutil
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

import aiohttp
import pytest

from malcolm.demo import demo_process
from malcolm.io.web import start_web_server

GET = "malcolm:core/Get:1.0"
PUT = "malcolm:core/Put:1.0"
POST = "malcolm:core/Post:1.0"
SUBSCRIBE = "malcolm:core/Subscribe:1.0"
UNSUBSCRIBE = "malcolm:core/Unsubscribe:1.0"
RETURN = "malcolm:core/Return:1.0"
ERROR = "malcolm:core/Error:1.0"
UPDATE = "malcolm:core/Update:1.0"
DELTA = "malcolm:core/Delta:1.0"


class Served:
    """The demo process and its web server, on a loop in another thread."""

    def __init__(
        self,
        process_factory: Callable[[], Any] = demo_process,
        extras: Callable[[Any], Any] | None = None,
    ) -> None:
        """``extras(process)`` (a coroutine function) adds to the process
        before it starts; what it returns is closed after it stops."""
        self.extras = extras
        self.extra = None
        self.loop = asyncio.new_event_loop()
        self.thread = threading.Thread(target=self.loop.run_forever, daemon=True)
        self.thread.start()
        self.process = process_factory()
        self.server = self.call(self._start)

    async def _start(self):
        if self.extras is not None:
            self.extra = await self.extras(self.process)
        await self.process.start()
        return await start_web_server(self.process, 0, "127.0.0.1")

    @property
    def url(self) -> str:
        return self.server.url

    @property
    def ws_url(self) -> str:
        return self.server.url + "ws"

    def call(self, func: Callable[[], Any], timeout: float = 30) -> Any:
        """Run ``func()`` (awaited if a coroutine function) on the server's loop."""

        async def run():
            result = func()
            if asyncio.iscoroutine(result):
                result = await result
            return result

        return asyncio.run_coroutine_threadsafe(run(), self.loop).result(timeout)

    def get(self, path: list[str]) -> Any:
        """What the process holds at ``path`` (read on its loop)."""
        return json.loads(json.dumps(self.call(lambda: self.process.get(path))))

    def close(self) -> None:
        async def stop():
            await self.server.close()
            await self.process.stop()
            if self.extra is not None:
                await self.extra.close()

        try:
            self.call(stop)
        finally:
            self.loop.call_soon_threadsafe(self.loop.stop)
            self.thread.join(10)
            self.loop.close()


@pytest.fixture
def served():
    s = Served()
    try:
        yield s
    finally:
        s.close()


class Client:
    """A WebSocket client of the JSON protocol; replies are kept by id."""

    def __init__(self, ws: aiohttp.ClientWebSocketResponse) -> None:
        self.ws = ws
        self.inbox: list[dict[str, Any]] = []
        self.next_id = 1

    async def send(self, message: dict[str, Any] | str) -> None:
        text = message if isinstance(message, str) else json.dumps(message)
        await self.ws.send_str(text)

    async def receive(self, timeout: float = 20) -> dict[str, Any]:
        msg = await self.ws.receive(timeout)
        assert msg.type == aiohttp.WSMsgType.TEXT, f"not a text message: {msg}"
        return json.loads(msg.data)

    async def wait_for(
        self, id_: int, typeids: tuple[str, ...] = (RETURN, ERROR), timeout: float = 20
    ) -> dict[str, Any]:
        """The first message for ``id_`` of one of ``typeids`` (kept ones first)."""
        for i, m in enumerate(self.inbox):
            if m["id"] == id_ and m["typeid"] in typeids:
                return self.inbox.pop(i)
        while True:
            m = await self.receive(timeout)
            if m["id"] == id_ and m["typeid"] in typeids:
                return m
            self.inbox.append(m)

    async def request(self, typeid: str, **fields: Any) -> dict[str, Any]:
        id_ = fields.pop("id", None)
        if id_ is None:
            id_ = self.next_id
            self.next_id += 1
        await self.send({"typeid": typeid, "id": id_, **fields})
        return await self.wait_for(id_)

    async def value(self, typeid: str, **fields: Any) -> Any:
        reply = await self.request(typeid, **fields)
        assert reply["typeid"] == RETURN, reply
        return reply["value"]

    def take(self, id_: int) -> list[dict[str, Any]]:
        """Every kept message for ``id_`` (removed from the inbox)."""
        mine = [m for m in self.inbox if m["id"] == id_]
        self.inbox = [m for m in self.inbox if m["id"] != id_]
        return mine


async def connect(session: aiohttp.ClientSession, served: Served) -> Client:
    return Client(await session.ws_connect(served.ws_url, max_msg_size=0))


def run(coro, timeout: float = 60) -> Any:
    """Run a test's client coroutine on a loop of its own."""
    return asyncio.run(asyncio.wait_for(coro, timeout))


# ---- the browser: Debian's chromium driven by playwright
CHROMIUM = "/usr/bin/chromium"


@pytest.fixture(scope="module")
def browser():
    """Chromium, for one module's tests (playwright's sync API keeps an asyncio
    loop running in this thread while it is open)."""
    if not os.path.exists(CHROMIUM):
        pytest.skip(f"{CHROMIUM} is not installed (apt-get install chromium)")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=["--no-sandbox"])
        try:
            yield b
        finally:
            b.close()


class Shots:
    """Saves screenshots to a temp dir, and to $MALCOLM_WEB_SHOTS if set."""

    def __init__(self, where: Path) -> None:
        self.where = where
        self.also = os.environ.get("MALCOLM_WEB_SHOTS")

    def __call__(self, page, name: str) -> Path:
        path = self.where / f"{name}.png"
        page.screenshot(path=str(path), full_page=True)
        assert path.stat().st_size > 1000
        if self.also:
            shutil.copy(path, Path(self.also) / path.name)
        return path


@pytest.fixture
def page(browser, served, tmp_path):
    """A page of the GUI on the served demo; errors in the page fail the test."""
    context = browser.new_context(viewport={"width": 1400, "height": 1000})
    pg = context.new_page()
    errors: list[str] = []
    pg.on("pageerror", lambda e: errors.append(str(e)))
    pg.shots = Shots(tmp_path)
    pg.served = served
    try:
        yield pg
    finally:
        context.close()
    assert not errors, f"the page raised: {errors}"

"""The Zebra2 (PandA) control port client: pipelined line commands over TCP.

One :class:`ControlClient` is one TCP connection to the box's control port
(8888 by default). Commands are sent as soon as they are asked for, several
may be in flight (pipelined), and replies are matched to them in order, as
the server answers strictly in order. Every reply has a timeout. An ``ERR``
reply raises :class:`Zebra2Error` with the server's text; the connection
stays open. When the box goes away every command in flight fails with
:class:`Zebra2Disconnected`; :meth:`ControlClient.connect` makes a new
connection (the owner decides when: see ``malcolm.parts.zebra2_manager``).

The reply forms (recorded in ``../shared/zebra2/README.md``): ``OK``,
``OK =value``, ``ERR message``, or ``!item`` lines ended by ``.``.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

from malcolm.core import BadValueError, MalcolmError, WaitTimeoutError

__all__ = [
    "DEFAULT_CONTROL_PORT",
    "DEFAULT_DATA_PORT",
    "DEFAULT_TIMEOUT",
    "ControlClient",
    "Reply",
    "Zebra2Disconnected",
    "Zebra2Error",
    "Zebra2Timeout",
]

DEFAULT_CONTROL_PORT = 8888
DEFAULT_DATA_PORT = 8889
#: seconds to wait for a reply (or a connection) unless told otherwise
DEFAULT_TIMEOUT = 5.0
#: the server closes the connection on a line of this many bytes or more
MAX_LINE = 1024


class Zebra2Error(BadValueError):
    """The box answered ``ERR``: ``str(e)`` names the command and gives the
    server's text; ``e.text`` is the text alone (without ``ERR ``)."""

    def __init__(self, command: str, text: str) -> None:
        self.command = command
        self.text = text
        super().__init__(f"{command}: {text}")


class Zebra2Disconnected(MalcolmError):
    """Not connected to the box, or the connection was lost."""


class Zebra2Timeout(Zebra2Disconnected, WaitTimeoutError):
    """No reply in time (the connection is then dropped: replies would no
    longer match their commands)."""


@dataclass(frozen=True)
class Reply:
    """One reply: ``value`` for ``OK =value``, ``lines`` for a list reply
    (without the ``!``), neither for a plain ``OK``."""

    value: str | None = None
    lines: tuple[str, ...] | None = None


class ControlClient:
    """A pipelined connection to a box's control port."""

    def __init__(
        self,
        host: str = "localhost",
        port: int = DEFAULT_CONTROL_PORT,
        timeout: float = DEFAULT_TIMEOUT,
    ) -> None:
        self.host = host
        self.port = port
        self.timeout = timeout
        self._reader: asyncio.StreamReader | None = None
        self._writer: asyncio.StreamWriter | None = None
        self._pending: deque[tuple[str, asyncio.Future[Reply]]] = deque()
        self._read_task: asyncio.Task[None] | None = None
        self._lost: str | None = "not connected"

    @property
    def address(self) -> str:
        return f"{self.host}:{self.port}"

    @property
    def connected(self) -> bool:
        return self._lost is None

    @property
    def why_not_connected(self) -> str | None:
        """Why there is no connection (None when connected)."""
        return self._lost

    async def connect(self, timeout: float | None = None) -> None:
        """Open a new connection (closing any old one)."""
        await self.close()
        try:
            self._reader, self._writer = await asyncio.wait_for(
                asyncio.open_connection(self.host, self.port),
                timeout or self.timeout,
            )
        except (TimeoutError, OSError) as e:
            self._lost = f"cannot connect: {type(e).__name__}: {e}".rstrip(": ")
            raise Zebra2Disconnected(f"{self.address}: {self._lost}") from None
        self._lost = None
        self._read_task = asyncio.get_running_loop().create_task(self._read_loop())

    async def close(self) -> None:
        """Drop the connection; commands in flight fail."""
        self._drop("closed")
        task, self._read_task = self._read_task, None
        if task is not None and task is not asyncio.current_task():
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task
        writer, self._writer = self._writer, None
        self._reader = None
        if writer is not None:
            writer.close()
            with contextlib.suppress(Exception):
                await writer.wait_closed()

    # ---- sending
    def send_lines(self, commands: Sequence[str]) -> list[asyncio.Future[Reply]]:
        """Send ``commands`` (one reply each) at once; the futures of their
        replies, in order. A table write is one command of several lines."""
        if self._lost is not None or self._writer is None:
            raise Zebra2Disconnected(f"{self.address}: {self._lost or 'closed'}")
        loop = asyncio.get_running_loop()
        futures = []
        data = []
        for command in commands:
            for line in command.split("\n"):
                if len(line.encode()) + 1 >= MAX_LINE:
                    raise BadValueError(
                        f"{command[:40]}...: a line of {len(line) + 1} bytes is"
                        f" longer than the box takes ({MAX_LINE - 1})"
                    )
            fut: asyncio.Future[Reply] = loop.create_future()
            self._pending.append((command, fut))
            futures.append(fut)
            data.append(command + "\n")
        self._writer.write("".join(data).encode())
        return futures

    async def _wait(self, command: str, fut: asyncio.Future[Reply]) -> Reply:
        if not fut.done():
            # one timer a reply (cheaper than wait_for, which makes a task)
            loop = asyncio.get_running_loop()
            timer = loop.call_later(self.timeout, self._timed_out, command, fut)
            try:
                await fut
            finally:
                timer.cancel()
        return fut.result()

    def _timed_out(self, command: str, fut: asyncio.Future[Reply]) -> None:
        if fut.done():
            return
        why = f"no reply to {command.splitlines()[0]!r} in {self.timeout} s"
        fut.set_exception(Zebra2Timeout(f"{self.address}: {why}"))
        self._drop(why)

    async def send(self, command: str) -> Reply:
        """Send one command and return its reply (Zebra2Error on ``ERR``)."""
        (fut,) = self.send_lines([command])
        return await self._wait(command, fut)

    async def send_many(self, commands: Sequence[str]) -> list[Reply | Exception]:
        """Pipeline ``commands``; each reply, or the Zebra2Error of its ``ERR``.
        A lost connection or a timeout is raised."""
        futures = self.send_lines(commands)
        out: list[Reply | Exception] = []
        for command, fut in zip(commands, futures):
            try:
                out.append(await self._wait(command, fut))
            except Zebra2Error as e:
                out.append(e)
        return out

    async def get(self, target: str) -> str:
        """``target?`` -> the value of ``OK =value``."""
        reply = await self.send(f"{target}?")
        if reply.value is None:
            raise Zebra2Error(f"{target}?", f"expected a value, got {reply}")
        return reply.value

    async def get_lines(self, target: str) -> list[str]:
        """``target?`` -> the items of a list reply."""
        reply = await self.send(f"{target}?")
        if reply.lines is None:
            raise Zebra2Error(f"{target}?", f"expected a list, got {reply}")
        return list(reply.lines)

    async def put(self, target: str, value: str) -> None:
        """``target=value``."""
        await self.send(f"{target}={value}")

    async def put_table(self, target: str, words: Sequence[int]) -> None:
        """A fixed table write: ``target<``, one word a line, an empty line."""
        body = "".join(f"\n{int(w) & 0xFFFFFFFF}" for w in words)
        await self.send(f"{target}<{body}\n")

    # ---- receiving
    def _drop(self, why: str) -> None:
        if self._lost is None:
            self._lost = why
        pending, self._pending = self._pending, deque()
        for command, fut in pending:
            if not fut.done():
                fut.set_exception(
                    Zebra2Disconnected(
                        f"{self.address}: {why} ({command!r} unanswered)"
                    )
                )
                fut.exception()  # retrieved: nobody may be waiting any more
        if self._writer is not None:
            self._writer.close()

    async def _read_loop(self) -> None:
        reader = self._reader
        assert reader is not None
        lines: list[str] = []
        why = "connection closed by the box"
        try:
            while True:
                raw = await reader.readline()
                if not raw.endswith(b"\n"):
                    break
                line = raw[:-1].decode(errors="replace")
                if lines or line.startswith("!") or line == ".":
                    if line == ".":
                        self._answer(Reply(lines=tuple(x[1:] for x in lines)))
                        lines = []
                    else:
                        lines.append(line)
                elif line == "OK":
                    self._answer(Reply())
                elif line.startswith("OK ="):
                    self._answer(Reply(value=line[4:]))
                elif line.startswith("ERR"):
                    self._answer(None, line[4:] if line.startswith("ERR ") else line)
                else:
                    why = f"unexpected reply {line[:80]!r}"
                    break
        except (OSError, asyncio.IncompleteReadError) as e:
            why = f"connection lost: {type(e).__name__}: {e}"
        self._drop(why)

    def _answer(self, reply: Reply | None, error: str = "") -> None:
        if not self._pending:
            return  # an answer to a command nobody waits for (cannot happen)
        command, fut = self._pending.popleft()
        if fut.done():
            return
        if reply is None:
            fut.set_exception(Zebra2Error(command.split("\n")[0], error))
        else:
            fut.set_result(reply)

"""Box: one Zebra2 control connection kept alive, polled and dispatched.

A :class:`Box` owns a :class:`~.control.ControlClient`, the box's
:class:`~.layout.BoxLayout` and a poll loop:

- :meth:`Box.start` connects and introspects (raising if it cannot);
- :meth:`Box.run` polls ``*CHANGES?`` every ``poll_period`` seconds and
  hands each change to the callbacks watching its ``(block, field,
  attribute)``; a table change (``!SEQ.TABLE<``) is re-read (``SEQ.TABLE?``)
  and handed on as its words. When the connection is lost (the next poll
  fails at once, or a reply times out) the state watchers hear it; the loop
  tries again every ``poll_period`` (at most :data:`RETRY_PERIOD` apart),
  and after a reconnection the first ``*CHANGES?`` reports every value;
- :meth:`Box.write`, :meth:`Box.write_table`, :meth:`Box.call` are one
  write each, pipelined with a read-back of the same target, on the same
  connection as the polls (so they are ordered with them).

Everything runs on the asyncio loop that started the box.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Callable, Sequence

from .control import (
    DEFAULT_CONTROL_PORT,
    DEFAULT_TIMEOUT,
    ControlClient,
    Reply,
    Zebra2Disconnected,
    Zebra2Error,
)
from .layout import BoxLayout, introspect
from .values import Change, parse_change

__all__ = ["RETRY_PERIOD", "Box", "ChangeCallback", "StateCallback"]

log = logging.getLogger(__name__)

#: the longest wait between two attempts to reconnect, in seconds
RETRY_PERIOD = 1.0

#: called with each change (a table's ``value`` is its words, space-separated)
ChangeCallback = Callable[[Change], None]
#: called with (connected, message) when the connection changes
StateCallback = Callable[[bool, str], None]


class Box:
    """A Zebra2 box on ``host:control_port``, polled every ``poll_period`` s."""

    def __init__(
        self,
        host: str = "localhost",
        control_port: int = DEFAULT_CONTROL_PORT,
        poll_period: float = 0.1,
        timeout: float = DEFAULT_TIMEOUT,
    ) -> None:
        self.client = ControlClient(host, control_port, timeout)
        self.poll_period = float(poll_period)
        self.layout: BoxLayout | None = None
        self._watchers: dict[tuple[str, str, str | None], list[ChangeCallback]] = {}
        self._state_watchers: list[StateCallback] = []
        self._batch_watchers: list[Callable[[list[Change]], None]] = []
        self._connected = False
        self._task: asyncio.Task[None] | None = None
        #: polls answered so far (tests and benchmarks wait on it)
        self.polls = 0

    @property
    def address(self) -> str:
        return self.client.address

    @property
    def connected(self) -> bool:
        return self._connected and self.client.connected

    # ---- lifecycle
    async def start(self) -> BoxLayout:
        """Connect and introspect; Zebra2Disconnected if the box is not there."""
        await self.client.connect()
        self.layout = await introspect(self.client)
        self._set_state(True, "")
        return self.layout

    def run(self) -> asyncio.Task[None]:
        """Start polling (once); the task ends with :meth:`close`."""
        if self._task is None or self._task.done():
            self._task = asyncio.get_running_loop().create_task(self._poll_loop())
        return self._task

    async def stop_polling(self) -> None:
        task, self._task = self._task, None
        if task is not None:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task

    async def close(self) -> None:
        """Stop polling and close the connection."""
        await self.stop_polling()
        await self.client.close()
        self._set_state(False, "closed")

    # ---- watching
    def watch(self, block: str, field: str, attribute: str | None, cb: ChangeCallback):
        """Call ``cb(change)`` for each change of ``block.field[.attribute]``."""
        self._watchers.setdefault((block, field, attribute), []).append(cb)

    def watch_batches(self, cb: Callable[[list[Change]], None]) -> None:
        """Call ``cb(changes)`` after each poll that reported something."""
        self._batch_watchers.append(cb)

    def watch_state(self, cb: StateCallback) -> None:
        """Call ``cb(connected, message)`` when the connection changes."""
        self._state_watchers.append(cb)

    def _set_state(self, connected: bool, message: str) -> None:
        if connected == self._connected:
            return
        self._connected = connected
        for cb in list(self._state_watchers):
            try:
                cb(connected, message)
            except Exception:
                log.exception("%s: state watcher raised", self.address)

    # ---- polling
    async def poll(self) -> list[Change]:
        """One ``*CHANGES?``; tables it names are re-read; watchers called."""
        lines = await self.client.get_lines("*CHANGES")
        changes = [c for c in map(parse_change, lines) if c is not None]
        tables = [c for c in changes if c.kind == "table"]
        if tables:
            replies = await self.client.send_many(
                [f"{c.block}.{c.field}?" for c in tables]
            )
            read = {}
            for c, reply in zip(tables, replies):
                if isinstance(reply, Reply) and reply.lines is not None:
                    read[id(c)] = Change(
                        c.block, c.field, None, "table", " ".join(reply.lines)
                    )
                else:
                    read[id(c)] = Change(c.block, c.field, None, "error", str(reply))
            changes = [read.get(id(c), c) for c in changes]
        self.polls += 1
        self._dispatch(changes)
        return changes

    def _dispatch(self, changes: Sequence[Change]) -> None:
        for c in changes:
            for cb in self._watchers.get((c.block, c.field, c.attribute), ()):
                try:
                    cb(c)
                except Exception:
                    log.exception("%s: watcher of %s raised", self.address, c)
        if changes:
            for batch_cb in list(self._batch_watchers):
                try:
                    batch_cb(list(changes))
                except Exception:
                    log.exception("%s: batch watcher raised", self.address)

    async def _poll_loop(self) -> None:
        while True:
            if not self.client.connected:
                self._set_state(False, self.client.why_not_connected or "lost")
                try:
                    await self.client.connect()
                except Zebra2Disconnected as e:
                    self._set_state(False, str(e))
                    await asyncio.sleep(min(self.poll_period, RETRY_PERIOD))
                    continue
            try:
                await self.poll()
                self._set_state(True, "")
            except Zebra2Disconnected as e:
                self._set_state(False, str(e))
                continue
            except Zebra2Error as e:  # *CHANGES? refused: should not happen
                log.warning("%s: %s", self.address, e)
            await asyncio.sleep(self.poll_period)

    # ---- writing
    def _check(self) -> None:
        if not self.client.connected:
            raise Zebra2Disconnected(
                f"{self.address}: not connected"
                f" ({self.client.why_not_connected or 'lost'})"
            )

    async def write(self, target: str, text: str) -> str | None:
        """``target=text`` then ``target?``: the value read back (None if it
        cannot be read). Zebra2Error with the box's text if refused."""
        self._check()
        wrote, back = await self.client.send_many([f"{target}={text}", f"{target}?"])
        if isinstance(wrote, Exception):
            raise wrote
        if isinstance(back, Reply):
            return back.value
        return None

    async def write_table(self, target: str, words: Sequence[int]) -> list[int]:
        """A fixed table write then a read: the words the box now holds."""
        self._check()
        body = "".join(f"\n{int(w) & 0xFFFFFFFF}" for w in words)
        wrote, back = await self.client.send_many([f"{target}<{body}\n", f"{target}?"])
        if isinstance(wrote, Exception):
            raise wrote
        if isinstance(back, Reply) and back.lines is not None:
            return [int(w, 0) for w in back.lines]
        return [int(w) & 0xFFFFFFFF for w in words]

    async def call(self, command: str) -> Reply:
        """Send one command (``*PCAP.ARM=``, ``SRGATE1.FORCE_SET=``)."""
        self._check()
        return await self.client.send(command)

"""The asyncio TCP servers: control port (commands) and data port (capture).

`serve_zebra2` binds both ports and returns a `Zebra2Server`; closing it
closes every connection.  Each control line is handled in arrival order, so
pipelined commands get their replies in order; a line of 1024 bytes or more
(with its ``\\n``) closes the connection without a reply, as the recorded
server does.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from datetime import UTC, datetime

from .box import Box
from .commands import Session
from .dataport import DataClient
from .layout import load_layout
from .simulation import Clock, RealClock, Simulation

log = logging.getLogger(__name__)

LINE_LIMIT = 1024


class Zebra2Server:
    """A running simulated box: its `Box`, `Simulation` and both servers."""

    def __init__(
        self,
        box: Box,
        sim: Simulation,
        host: str,
        control: asyncio.Server,
        data: asyncio.Server,
    ) -> None:
        self.box = box
        self.sim = sim
        self.host = host
        self._control = control
        self._data = data
        self.control_port: int = control.sockets[0].getsockname()[1]
        self.data_port: int = data.sockets[0].getsockname()[1]
        self._tasks: set[asyncio.Task] = set()
        self._writers: set[asyncio.StreamWriter] = set()
        #: (connected time, "config"/"data", peer) per open connection
        self.who: dict[asyncio.StreamWriter, tuple[str, str, str]] = {}

    async def close(self) -> None:
        """Stop listening and close every connection."""
        self._control.close()
        self._data.close()
        await self.sim.close()
        for writer in list(self._writers):
            writer.close()
        for task in list(self._tasks):
            task.cancel()
        for task in list(self._tasks):
            with contextlib.suppress(BaseException):
                await task
        await self._control.wait_closed()
        await self._data.wait_closed()

    def _who_lines(self) -> list[str]:
        return [f"{t} {kind} {peer} " for t, kind, peer in self.who.values()]

    def _track(self, writer: asyncio.StreamWriter, kind: str) -> None:
        task = asyncio.current_task()
        assert task is not None
        self._tasks.add(task)
        self._writers.add(writer)
        peer = writer.get_extra_info("peername") or ("?", 0)
        now = datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%S.%f")[:-3] + "Z"
        self.who[writer] = (now, kind, f"{peer[0]}:{peer[1]}")

    def _untrack(self, writer: asyncio.StreamWriter) -> None:
        task = asyncio.current_task()
        self._tasks.discard(task)  # type: ignore[arg-type]
        self._writers.discard(writer)
        self.who.pop(writer, None)
        writer.close()

    async def handle_control(
        self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter
    ) -> None:
        self._track(writer, "config")
        session = Session(self.box, self.sim)
        session.who_lines = self._who_lines
        try:
            while True:
                try:
                    raw = await reader.readuntil(b"\n")
                except asyncio.LimitOverrunError:
                    return  # the line limit: close without a reply
                except asyncio.IncompleteReadError:
                    return
                if len(raw) >= LINE_LIMIT:
                    return
                line = raw[:-1].decode("utf-8", "surrogateescape")
                reply = session.feed_line(line)
                if reply is not None:
                    out = "".join(r + "\n" for r in reply)
                    writer.write(out.encode("utf-8", "surrogateescape"))
                    await writer.drain()
        except (ConnectionError, asyncio.CancelledError):
            pass
        except Exception:  # a bug must not kill the server
            log.exception("zebra2 sim: control connection failed")
        finally:
            self._untrack(writer)

    async def handle_data(
        self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter
    ) -> None:
        self._track(writer, "data")
        try:
            try:
                raw = await reader.readuntil(b"\n")
            except (asyncio.LimitOverrunError, asyncio.IncompleteReadError):
                return
            client = DataClient.from_options(raw[:-1].decode("latin-1"), writer)
            if client is None:
                writer.write(b"ERR Invalid data capture option\n")
                await writer.drain()
                return
            if client.status:
                writer.write(b"OK\n")
            await self.sim.capture.serve_client(client, reader)
        except (ConnectionError, asyncio.CancelledError):
            pass
        except Exception:
            log.exception("zebra2 sim: data connection failed")
        finally:
            self._untrack(writer)


async def serve_zebra2(
    host: str = "127.0.0.1",
    control_port: int = 8888,
    data_port: int = 8889,
    layout: str = "tier2",
    *,
    clock: Clock | None = None,
    disarm_completion: str = "Disarmed",
) -> Zebra2Server:
    """Start a simulated PandA on ``host``; port 0 picks a free port.

    ``clock`` drives the simulated blocks (default: real time);
    ``disarm_completion`` is what ``*PCAP.DISARM=`` ends a capture with
    (``Disarmed`` as hardware does, ``Ok`` as the recorded simulations did).
    """
    box = Box(load_layout(layout))
    sim = Simulation(box, clock or RealClock(), disarm_completion=disarm_completion)
    holder: dict[str, Zebra2Server] = {}

    async def on_control(r: asyncio.StreamReader, w: asyncio.StreamWriter) -> None:
        await holder["server"].handle_control(r, w)

    async def on_data(r: asyncio.StreamReader, w: asyncio.StreamWriter) -> None:
        await holder["server"].handle_data(r, w)

    control = await asyncio.start_server(
        on_control, host, control_port, limit=LINE_LIMIT
    )
    try:
        data = await asyncio.start_server(on_data, host, data_port, limit=LINE_LIMIT)
    except BaseException:
        control.close()
        raise
    server = Zebra2Server(box, sim, host, control, data)
    holder["server"] = server
    return server

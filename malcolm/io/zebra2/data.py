"""The Zebra2 (PandA) data port client (8889 by default).

:class:`DataClient` connects, sends the option line the ``pandablocks``
library sends (``XML FRAMED SCALED`` or ``XML FRAMED RAW``) and parses what
comes back with that library's sans-IO ``DataConnection``: ``ReadyData``
once the box said ``OK``, then per experiment ``StartData`` (the header:
fields, types, scale/offset/units), ``FrameData`` (numpy structured arrays
of samples) and ``EndData`` (samples and reason from the ``END`` line).
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator

from pandablocks.connections import DataConnection
from pandablocks.responses import Data, EndData, FrameData, ReadyData, StartData

from .control import DEFAULT_DATA_PORT, DEFAULT_TIMEOUT, Zebra2Disconnected

__all__ = ["DataClient", "EndData", "FrameData", "ReadyData", "StartData"]

#: bytes read from the socket at a time
CHUNK = 1 << 20


class DataClient:
    """One data port connection; :meth:`connect` then ``async for`` the data."""

    def __init__(
        self,
        host: str = "localhost",
        port: int = DEFAULT_DATA_PORT,
        scaled: bool = True,
        timeout: float = DEFAULT_TIMEOUT,
    ) -> None:
        self.host = host
        self.port = port
        self.scaled = scaled
        self.timeout = timeout
        self._reader: asyncio.StreamReader | None = None
        self._writer: asyncio.StreamWriter | None = None
        self._conn = DataConnection()
        self._early: list[Data] = []

    @property
    def address(self) -> str:
        return f"{self.host}:{self.port}"

    async def connect(self) -> None:
        """Connect and wait for the box's ``OK`` (ready for the next ARM)."""
        try:
            self._reader, self._writer = await asyncio.wait_for(
                asyncio.open_connection(self.host, self.port, limit=CHUNK),
                self.timeout,
            )
        except (TimeoutError, OSError) as e:
            raise Zebra2Disconnected(
                f"data port {self.address}: cannot connect: {type(e).__name__}: {e}"
            ) from None
        self._writer.write(self._conn.connect(self.scaled))
        ready = False
        while not ready:
            chunk = await asyncio.wait_for(self._reader.read(CHUNK), self.timeout)
            if not chunk:
                raise Zebra2Disconnected(f"data port {self.address}: closed")
            for data in self._conn.receive_bytes(chunk, flush_every_frame=False):
                if isinstance(data, ReadyData):
                    ready = True
                else:
                    self._early.append(data)

    async def close(self) -> None:
        writer, self._writer = self._writer, None
        if writer is not None:
            writer.close()
            with contextlib.suppress(Exception):
                await writer.wait_closed()

    async def experiment(self) -> AsyncIterator[StartData | FrameData | EndData]:
        """The next experiment: its StartData, FrameData chunks (one per read
        of the socket), then its EndData. Zebra2Disconnected if it is lost."""
        assert self._reader is not None, "connect() first"
        pending = list(self._early)
        self._early = []
        while True:
            for i, data in enumerate(pending):
                if isinstance(data, EndData):
                    self._early = pending[i + 1 :]  # the next experiment's
                    yield data
                    return
                yield data  # type: ignore[misc]
            chunk = await self._reader.read(CHUNK)
            if not chunk:
                raise Zebra2Disconnected(
                    f"data port {self.address}: closed before the END of the experiment"
                )
            pending = list(self._conn.receive_bytes(chunk, flush_every_frame=False))
            if not any(isinstance(d, EndData) for d in pending):
                pending += list(self._conn.flush())

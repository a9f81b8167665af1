"""How fast the simulated PandA streams a capture (issue 11, item 4).

    /work/shared/tools/isolated .venv/bin/python -m benchmarks.zebra2_sim \\
        [--seconds 10]

A CLOCK of the given period triggers PCAP, capturing COUNTER1.OUT and
PCAP.TS_TRIG (the capture of a PCAP part), for ``--seconds`` of real time.
Each row is one data client: a bare asyncio socket reading ``XML FRAMED
RAW``/``SCALED`` (the simulator alone), or the ``pandablocks`` library's
own AsyncioClient (its parser too).  "measured" is the samples per second
delivered; the note gives the samples made, those delivered (``END n``) and
how the experiment ended: ``Data overrun`` if the client or the simulator
fell behind (one second of samples not yet made, or 256 MiB unsent), as the
FPGA's buffer would.  The target (the issue's): a 1 us clock period
(1 MHz) sustained with nothing lost; the last rows give the largest rate
sustained here.
"""

from __future__ import annotations

import argparse
import asyncio
import time

from benchmarks.table import Row, render
from malcolm.sim.zebra2 import serve_zebra2

HOST = "127.0.0.13"  # pandablocks' client always uses ports 8888/8889
TARGET = "1e6 samples/s, none lost"
SETUP = [
    "CLOCK1.PERIOD.UNITS=us",
    "CLOCK1.ENABLE=ONE",
    "COUNTER1.ENABLE=ONE",
    "COUNTER1.TRIG=CLOCK1.OUT",
    "COUNTER1.STEP=1",
    "PCAP.TRIG=CLOCK1.OUT",
    "PCAP.GATE=ONE",
    "*CAPTURE=",
    "COUNTER1.OUT.CAPTURE=Value",
    "PCAP.TS_TRIG.CAPTURE=Value",
]


class Control:
    def __init__(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter):
        self.reader, self.writer = reader, writer

    async def ask(self, *commands: str) -> list[str]:
        self.writer.write("".join(c + "\n" for c in commands).encode())
        return [(await self.reader.readline()).decode().strip() for _ in commands]


async def socket_client(options: str, ready: asyncio.Event) -> tuple[int, str]:
    """Read one experiment as bytes; the END line's count and reason."""
    reader, writer = await asyncio.open_connection(HOST, 8889)
    writer.write(options.encode() + b"\n")
    await reader.readline()  # OK
    ready.set()
    tail = b""
    while True:
        chunk = await reader.read(1 << 20)
        if not chunk:
            raise ConnectionError("data port closed")
        tail = (tail + chunk)[-64:]
        at = tail.find(b"END ")
        if at >= 0 and tail.endswith(b"\n"):
            writer.close()
            _, n, reason = tail[at:].decode().split(" ", 2)
            return int(n), reason.strip()


async def pandablocks_client(scaled: bool, ready: asyncio.Event) -> tuple[int, str]:
    from pandablocks.asyncio import AsyncioClient
    from pandablocks.responses import EndData, FrameData, ReadyData

    rows = 0
    async with AsyncioClient(HOST) as client:
        async for data in client.data(scaled=scaled, frame_timeout=30):
            if isinstance(data, ReadyData):
                ready.set()
            elif isinstance(data, FrameData):
                rows += len(data.data)
            elif isinstance(data, EndData):
                assert data.samples == rows
                return rows, data.reason.value
    raise ConnectionError("data port closed")


async def one_run(period_us: float, seconds: float, client: str) -> Row:
    server = await serve_zebra2(HOST, 8888, 8889, "tier2")
    try:
        reader, writer = await asyncio.open_connection(HOST, 8888)
        control = Control(reader, writer)
        await control.ask(*SETUP, f"CLOCK1.PERIOD={period_us}")
        ready = asyncio.Event()
        if client.startswith("pandablocks"):
            task = asyncio.ensure_future(pandablocks_client("scaled" in client, ready))
        else:
            task = asyncio.ensure_future(socket_client(client, ready))
        await asyncio.wait_for(ready.wait(), 10)
        await control.ask("*PCAP.ARM=", "PCAP.ENABLE=ONE")
        start = time.perf_counter()
        await asyncio.sleep(seconds)
        await control.ask("PCAP.ENABLE=ZERO")
        made = int((await control.ask("*PCAP.CAPTURED?"))[0].split("=")[1])
        delivered, reason = await asyncio.wait_for(task, 120)
        elapsed = time.perf_counter() - start
        writer.close()
    finally:
        await server.close()
    rate = 1e6 / period_us
    return Row(
        f"{client}, {rate:.3g} Hz clock",
        delivered / elapsed,
        "samples/s",
        TARGET,
        "-",
        f"made {made}, END {delivered} {reason}",
    )


async def main(seconds: float, periods: list[float]) -> list[Row]:
    rows = []
    for client in ("XML FRAMED RAW", "XML FRAMED SCALED", "pandablocks raw"):
        rows.append(await one_run(1.0, seconds, client))
    best = None
    for period in periods:
        row = await one_run(period, seconds, "XML FRAMED RAW")
        rows.append(row)
        if row.note.endswith(" Ok"):
            best = row
    if best is not None:
        rows.append(
            Row("largest rate sustained, nothing lost", best.measured,
                "samples/s", TARGET, "-", best.case)
        )  # fmt: skip
    print(render(rows, ""))
    return rows


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0)
    args = parser.parse_args()
    asyncio.run(main(args.seconds, [0.5, 0.2, 0.1]))

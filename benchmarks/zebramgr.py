"""Issue 13's figures for the ZebraManager alone, against the simulator.

    ../shared/tools/isolated .venv/bin/python -m benchmarks.zebramgr [--repeats 5]

Run it under ``isolated``: the simulator (``malcolm sim-zebra2``, a
subprocess) binds 127.0.0.1:8888/8889 of that private namespace.

- configure of the ZebraManager (``zebra2.ZebraManager``) for a 10x10 snake
  grid and a 10,000-point spiral, from the call to Armed (the scan's
  points, the setup batch, the data connection, the empty file, ARM),
  median of ``--repeats``; beside each, the raw libraries doing the same
  work (a bare asyncio socket sending the same pipelined commands and
  reading the replies, the ``pandablocks`` library's ``DataConnection`` on
  a bare data socket, h5py making the same empty file) and the single-layer
  demo scan's configure (``malcolm demo``'s SCAN) of the same grid, which
  issue 13 says the whole hierarchy must stay within 3x of;
- the run's overhead per point of a 10,000-point line at 100 us a point:
  (run time - the points' total duration) / points, median of
  ``--repeats``, beside the raw libraries doing the same run (the same
  commands that start the clock on a bare socket, the data read with
  ``DataConnection`` to the ``END``, written with h5py), against issue 13's
  0.1 ms per point for the whole hierarchy.
"""

from __future__ import annotations

import argparse
import asyncio
import tempfile
import time
from pathlib import Path
from typing import Any

import h5py
from pandablocks.connections import DataConnection
from pandablocks.responses import EndData, FrameData, ReadyData

from benchmarks.demo_scan import grid, spiral
from benchmarks.table import Row, median, render
from benchmarks.zebra2 import CONTROL, DATA, HOST, start_sim, stop_sim
from malcolm.config.build import build_definition
from malcolm.core import Process
from malcolm.demo import demo_process
from malcolm.parts.zebra2_scan import run_commands, setup_commands
from malcolm.parts.zebra2_scan_file import create_scan_file
from malcolm.scan import gda

MRI = "BENCH:ZEBRA"
PERIOD = 100e-6
SOURCE = "targets from issue 13 (the whole hierarchy's)"


async def zebra_process() -> Process:
    process = Process("zebramgr-bench")
    params = {"host": HOST, "control_port": CONTROL, "data_port": DATA}
    build_definition("zebra2.ZebraManager", params, MRI, process=process)
    await process.start()
    return process


async def malcolm_configure(
    process: Process, generator: dict[str, Any], tmp: Path
) -> float:
    params = {"generator": generator, "fileDir": str(tmp), "formatName": "bench"}
    start = time.perf_counter()
    await process.post([MRI, "configure"], params)
    elapsed = time.perf_counter() - start
    await process.post([MRI, "abort"])
    await process.post([MRI, "reset"])
    return elapsed


class RawBox:
    """The same work on bare sockets: pipelined commands, DataConnection."""

    def __init__(self, host: str = HOST, control: int = CONTROL, data: int = DATA):
        self.address = (host, control, data)

    async def open(self) -> None:
        await self.open_control()
        await self.open_data()

    async def open_control(self) -> None:
        host, control, _ = self.address
        self.reader, self.writer = await asyncio.open_connection(host, control)

    async def open_data(self) -> None:
        host, _, data = self.address
        self.dreader, self.dwriter = await asyncio.open_connection(host, data)
        self.conn = DataConnection()
        self.dwriter.write(self.conn.connect(True))
        ready = False
        while not ready:
            got = list(self.conn.receive_bytes(await self.dreader.read(1 << 16)))
            ready = any(isinstance(d, ReadyData) for d in got)

    async def send(self, commands: list[str]) -> None:
        self.writer.write("".join(c + "\n" for c in commands).encode())
        for command in commands:
            reply = await self.reader.readline()
            assert reply.startswith(b"OK"), (command, reply)

    async def read_to_end(self, path: Path) -> int:
        """One experiment into ``path`` (h5py, in a thread): rows."""
        rows = 0
        with h5py.File(path, "a") as f:
            ds = f["COUNTER1.OUT.Value"]
            while True:
                chunk = await self.dreader.read(1 << 20)
                for d in list(self.conn.receive_bytes(chunk)):
                    if isinstance(d, FrameData):
                        n = len(d.data)
                        ds.resize((rows + n,))
                        ds[rows:] = d.data["COUNTER1.OUT.Value"]
                        rows += n
                    elif isinstance(d, EndData):
                        return rows

    async def close(self) -> None:
        self.writer.close()
        self.dwriter.close()

    async def arm(self, points: int, period: float, path: Path) -> None:
        """The ZebraManager's configure with the control connection open
        (as the manager keeps it): the setup batch, a new data connection
        and the empty file at once, then ARM."""
        await asyncio.gather(
            self.send(setup_commands(0, points, period)),
            self.open_data(),
            asyncio.to_thread(create_scan_file, path, {}),
        )
        await self.send(["*PCAP.ARM="])

    async def disarm(self) -> None:
        """DISARM and the data connection closed (after :meth:`arm`)."""
        await self.send(["*PCAP.DISARM="])
        self.dwriter.close()


async def raw_configure(points: int, tmp: Path) -> float:
    start = time.perf_counter()
    raw = RawBox()
    await raw.open()
    await raw.send(setup_commands(0, points, PERIOD))
    await asyncio.to_thread(create_scan_file, tmp / "raw.h5", {})
    await raw.send(["*PCAP.ARM="])
    elapsed = time.perf_counter() - start
    await raw.send(["*PCAP.DISARM="])
    await raw.close()
    return elapsed


async def demo_configure(generator: dict[str, Any]) -> float:
    process = demo_process()
    await process.start()
    try:
        start = time.perf_counter()
        await process.post(["SCAN", "configure"], {"generator": generator})
        return time.perf_counter() - start
    finally:
        await process.stop()


async def malcolm_run(process: Process, points: int, tmp: Path) -> float:
    generator = gda.compound(gda.line("x", points), duration=PERIOD)
    params = {"generator": generator, "fileDir": str(tmp), "formatName": "bench"}
    await process.post([MRI, "configure"], params)
    start = time.perf_counter()
    await process.post([MRI, "run"])
    elapsed = time.perf_counter() - start
    assert process.get([MRI, "state", "value"]) == "Finished"
    return (elapsed - points * PERIOD) / points


async def raw_run(points: int, tmp: Path) -> float:
    raw = RawBox()
    await raw.open()
    await raw.send(setup_commands(0, points, PERIOD))
    path = tmp / "raw.h5"
    await asyncio.to_thread(create_scan_file, path, {})
    await raw.send(["*PCAP.ARM="])
    start = time.perf_counter()
    await raw.send(run_commands(0, points, PERIOD))
    rows = await raw.read_to_end(path)
    elapsed = time.perf_counter() - start
    await raw.close()
    assert rows == points, rows
    return (elapsed - points * PERIOD) / points


async def main(args: argparse.Namespace) -> list[Row]:
    rows: list[Row] = []
    n = args.repeats
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        process = await zebra_process()
        try:
            for label, generator in [
                ("10x10 snake grid", grid(100, 0.001)),
                ("10,000-point spiral", spiral(10_000, 0.001)),
            ]:
                points = 100 if "10x10" in label else 10_000
                ours = median([await malcolm_configure(process, generator, tmp)
                               for _ in range(n)])  # fmt: skip
                raw = median([await raw_configure(points, tmp) for _ in range(n)])
                demo = median([await demo_configure(generator) for _ in range(n)])
                rows.append(Row(f"configure, {label}", ours * 1e3, "ms",
                                f"<= 3x demo ({3 * demo * 1e3:.3g} ms)",
                                "30 ms (10x10, two layers)" if points == 100
                                else "-",
                                f"raw libraries {raw * 1e3:.3g} ms"
                                f" (x{ours / raw:.2g}); demo SCAN"
                                f" {demo * 1e3:.3g} ms"))  # fmt: skip
            ours = median([await malcolm_run(process, 10_000, tmp) for _ in range(n)])
            raw = median([await raw_run(10_000, tmp) for _ in range(n)])
            rows.append(Row("run overhead per point, 10,000 at 100 us", ours * 1e3,
                            "ms", "<= 0.1 ms", "-",
                            f"raw libraries {raw * 1e3:.3g} ms"
                            f" (x{ours / raw:.2g} as much)"))  # fmt: skip
        finally:
            await process.stop()
    return rows


def parse(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.zebramgr")
    parser.add_argument("--repeats", type=int, default=5, help="median of this many")
    return parser.parse_args(argv)


def run(argv: list[str] | None = None) -> None:
    args = parse(argv)
    proc = start_sim()
    try:
        print(render(asyncio.run(main(args)), SOURCE))
    finally:
        stop_sim(proc)


if __name__ == "__main__":
    run()

"""Issue 11's Zebra2 benchmarks, against the simulator in one run.

    ../shared/tools/isolated .venv/bin/python -m benchmarks.zebra2 [--quick]

Run it under ``isolated``: the simulator (``malcolm sim-zebra2``, a
subprocess) binds 127.0.0.1:8888/8889 of that private namespace, the ports
the ``pandablocks`` library's client always uses.

- introspection of the tier-2 box to ready child blocks: from
  ``Process.start()`` of a ``zebra2.Manager`` until it is Ready with its 19
  children (connect, five pipelined rounds of introspection, the blocks
  made, started, and the first ``*CHANGES?`` applied), median of 5;
- a ``*CHANGES?`` poll round trip through the manager (``Box.poll``: the
  command, the parse, the dispatch to the children's attributes) vs a bare
  asyncio socket sending the same command and reading to the ``.``,
  alternated, median of 300 each, with a 1 kHz clock running so that every
  poll reports changes;
- capture throughput into HDF5, samples/s: the box armed for ``--window``
  seconds at ``--rate`` triggers/s (COUNTER1, COUNTER2 Min Max Mean,
  TS_TRIG), time from ARM until the file is closed; malcolm's
  ``zebra2.Capture`` run (SCALED, h5py in a worker thread) vs the
  ``pandablocks`` library's ``write_hdf_files`` (its own data client,
  FrameProcessor and HDFWriter threads) on the same settings, median of 3;
- the same on one recorded stream, replayed as fast as the writers take
  it: an experiment of ``--window`` s at ``--rate`` recorded once from the
  simulator in both option formats (``XML FRAMED SCALED``, which malcolm
  uses, and ``XML FRAMED RAW``, which ``write_hdf_files`` uses), then
  served from 127.0.0.2:8889 to malcolm's ``capture_to_file`` and to
  ``write_hdf_files``; samples/s from connecting until the file is closed,
  median of 3;
- the largest rate (of 1 k, 10 k, 100 k, 1 M, 2 M, 4 M samples/s) malcolm's capture
  sustains for ``--sustain`` seconds (10) with nothing lost: the END
  reason is not an overrun, the file has every sample the box sent, and
  the file was closed within 10 % (+0.5 s) of the window (kept up).
"""

from __future__ import annotations

import argparse
import asyncio
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import h5py

from benchmarks.table import Row, median, render
from malcolm.config.build import build_definition
from malcolm.core import Process
from malcolm.scan import gda

HOST = "127.0.0.1"
CONTROL, DATA = 8888, 8889
FIELDS = ["COUNTER1.OUT Value", "COUNTER2.OUT Min Max Mean", "PCAP.TS_TRIG Value"]


def start_sim() -> subprocess.Popen[str]:
    cmd = [sys.executable, "-m", "malcolm", "sim-zebra2", "--host", HOST]
    cmd += ["--control-port", str(CONTROL), "--data-port", str(DATA)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    line = proc.stdout.readline()
    if "control" not in line:
        proc.kill()
        raise RuntimeError(f"sim-zebra2 did not start ({line!r}): run under isolated")
    return proc


def stop_sim(proc: subprocess.Popen[str]) -> None:
    proc.send_signal(signal.SIGTERM)
    proc.communicate(timeout=30)


class Raw:
    """A bare asyncio control connection."""

    def __init__(self, reader, writer) -> None:
        self.reader, self.writer = reader, writer

    @classmethod
    async def open(cls) -> Raw:
        return cls(*await asyncio.open_connection(HOST, CONTROL))

    async def ask(self, command: str) -> list[str]:
        self.writer.write(command.encode() + b"\n")
        line = (await self.reader.readline()).decode().rstrip("\n")
        if not (line.startswith("!") or line == "."):
            return [line]
        lines = []
        while line != ".":
            lines.append(line)
            line = (await self.reader.readline()).decode().rstrip("\n")
        return lines

    async def close(self) -> None:
        self.writer.close()


async def setup_box(raw: Raw, rate: float) -> None:
    period_ns = max(8, round(1e9 / rate / 8) * 8)  # whole 125 MHz ticks
    for command in [
        "CLOCK1.ENABLE=ZERO",
        "CLOCK1.PERIOD.UNITS=us",
        f"CLOCK1.PERIOD={period_ns / 1000}",
        "CLOCK1.WIDTH.UNITS=us",
        f"CLOCK1.WIDTH={period_ns / 2000}",
        "CLOCK1.ENABLE=ONE",
        f"CLOCK1.WIDTH={period_ns / 2000}",
        "COUNTER1.ENABLE=ONE",
        "COUNTER1.TRIG=CLOCK1.OUT",
        "COUNTER1.STEP=1",
        "COUNTER2.ENABLE=ONE",
        "COUNTER2.TRIG=CLOCK1.OUT",
        "COUNTER2.STEP=5",
        "PCAP.ENABLE=ONE",
        "PCAP.GATE=ONE",
        "PCAP.TRIG=CLOCK1.OUT",
        "*CAPTURE=",
        "COUNTER1.OUT.CAPTURE=Value",
        "COUNTER2.OUT.CAPTURE=Min Max Mean",
        "PCAP.TS_TRIG.CAPTURE=Value",
    ]:
        reply = await raw.ask(command)
        assert reply == ["OK"], (command, reply)


# ---- introspection
async def introspection_seconds(tmp: Path) -> float:
    process = Process("bench", designs_dir=str(tmp))
    params = {"host": HOST, "control_port": CONTROL, "poll_period": 0.1}
    build_definition("zebra2.Manager", params, "Z", process=process)
    start = time.perf_counter()
    await process.start()
    seconds = time.perf_counter() - start
    assert process.get_block("Z").state.value == "Ready"
    assert len(process.mris) == 20  # the manager and 19 children
    await process.stop()
    return seconds


# ---- poll round trip
async def poll_round_trips(n: int, tmp: Path) -> tuple[float, float]:
    raw = await Raw.open()
    await setup_box(raw, 1000)
    process = Process("bench", designs_dir=str(tmp))
    params = {"host": HOST, "control_port": CONTROL, "poll_period": 3600}
    build_definition("zebra2.Manager", params, "Z", process=process)
    await process.start()
    box = process.get_controller("Z").parts["zebra2"].box
    bare = await Raw.open()
    await bare.ask("*CHANGES?")  # its first call reports everything
    await box.poll()
    managed, plain = [], []
    for _ in range(n):
        t = time.perf_counter()
        await box.poll()
        managed.append(time.perf_counter() - t)
        t = time.perf_counter()
        await bare.ask("*CHANGES?")
        plain.append(time.perf_counter() - t)
    await bare.close()
    await raw.close()
    await process.stop()
    return median(managed), median(plain)


# ---- capture
async def malcolm_capture(
    path: Path, rate: float, window: float
) -> tuple[int, float, str]:
    """(samples, seconds from ARM to the file closed, END reason)."""
    raw = await Raw.open()
    await setup_box(raw, rate)
    process = Process("bench")
    params = {"host": HOST, "control_port": CONTROL, "data_port": DATA}
    build_definition("zebra2.Capture", params, "CAP", process=process)
    await process.start()
    samples = max(1, int(rate * window))
    generator = gda.compound(gda.line("x", samples), duration=1 / rate)
    await process.post(
        ["CAP", "configure"],
        {"generator": generator, "captureFields": FIELDS, "captureFile": str(path)},
    )
    start = time.perf_counter()
    try:
        await asyncio.wait_for(process.post(["CAP", "run"]), 5 * window + 10)
    finally:
        seconds = time.perf_counter() - start
        if process.get_block("CAP").state.value != "Finished":
            await process.stop()
            await raw.close()
    block = process.get_block("CAP")
    written, reason = block.captureEnd.value.split(" ", 1)
    await process.stop()
    await raw.close()
    with h5py.File(path, "r") as f:
        rows = {len(f[name]) for name in f}
    assert rows == {int(written)}, (rows, written)
    return int(written), seconds, reason


async def pandablocks_capture(
    path: Path, rate: float, window: float
) -> tuple[int, float]:
    from pandablocks.asyncio import AsyncioClient
    from pandablocks.hdf import write_hdf_files

    raw = await Raw.open()
    await setup_box(raw, rate)
    samples = max(1, int(rate * window))
    async with AsyncioClient(HOST) as client:
        writer = asyncio.ensure_future(
            write_hdf_files(client, iter([str(path)]), num=1, flush_period=0.1)
        )
        await asyncio.sleep(0.3)  # its data connection is made
        start = time.perf_counter()
        assert await raw.ask("*PCAP.ARM=") == ["OK"]
        deadline = time.perf_counter() + 5 * window + 10
        while int((await raw.ask("*PCAP.CAPTURED?"))[0][4:]) < samples:
            if (await raw.ask("*PCAP.COMPLETION?")) != ["OK =Busy"]:
                break  # ended by the box (an overrun)
            if time.perf_counter() > deadline:
                raise TimeoutError(f"pandablocks capture: not {samples} samples")
            await asyncio.sleep(0.001)
        await raw.ask("*PCAP.DISARM=")
        await writer
        seconds = time.perf_counter() - start
    captured = int((await raw.ask("*PCAP.CAPTURED?"))[0][4:])
    await raw.close()
    return captured, seconds


async def record_streams(rate: float, window: float) -> dict[bytes, bytes]:
    """One experiment as a SCALED and a RAW data client received it."""
    raw = await Raw.open()
    await setup_box(raw, rate)
    options = [b"XML FRAMED SCALED\n", b"XML FRAMED RAW\n"]
    got: dict[bytes, bytearray] = {o: bytearray() for o in options}
    conns = []
    for option in options:
        reader, writer = await asyncio.open_connection(HOST, DATA, limit=1 << 20)
        writer.write(option)
        conns.append((option, reader, writer))

    async def read(option, reader) -> None:
        while chunk := await reader.read(1 << 20):
            got[option] += chunk

    readers = [asyncio.ensure_future(read(o, r)) for o, r, _ in conns]
    await asyncio.sleep(0.3)
    assert await raw.ask("*PCAP.ARM=") == ["OK"]
    await asyncio.sleep(window)
    await raw.ask("*PCAP.DISARM=")
    while await raw.ask("*PCAP.COMPLETION?") == ["OK =Busy"]:
        await asyncio.sleep(0.05)
    await asyncio.sleep(1.0)  # the last bytes arrive
    for _, _, writer in conns:
        writer.close()
    await asyncio.gather(*readers, return_exceptions=True)
    await raw.close()
    return {o: bytes(b) for o, b in got.items()}


async def replay_capture(streams: dict[bytes, bytes], tmp: Path, i: int):
    """(malcolm samples/s, pandablocks samples/s) on the recorded streams."""
    from pandablocks.asyncio import AsyncioClient
    from pandablocks.hdf import write_hdf_files

    from malcolm.io.zebra2.data import DataClient
    from malcolm.io.zebra2.hdf import capture_to_file

    handlers: set[asyncio.Task] = set()

    async def serve(reader, writer) -> None:
        handlers.add(asyncio.current_task())
        try:
            option = await reader.readline()
            writer.write(streams[option])
            await writer.drain()
            await reader.read()  # until the client closes
        except (asyncio.CancelledError, ConnectionError):
            pass
        finally:
            writer.close()

    replay_host = "127.0.0.2"
    server = await asyncio.start_server(serve, replay_host, DATA)
    try:
        start = time.perf_counter()
        client = DataClient(replay_host, DATA, scaled=True)
        await client.connect()
        rows, end = await capture_to_file(client, tmp / f"r{i}.h5")
        ours = rows / (time.perf_counter() - start)
        await client.close()
        assert end is not None and rows == end.samples, (rows, end)
        start = time.perf_counter()
        path = tmp / f"q{i}.h5"
        await write_hdf_files(AsyncioClient(replay_host), iter([str(path)]), num=1)
        theirs = rows / (time.perf_counter() - start)
        with h5py.File(path, "r") as f:
            assert {len(f[n]) for n in f} == {rows}
    finally:
        server.close()
        for task in handlers:
            task.cancel()
        await asyncio.gather(*handlers, return_exceptions=True)
        await server.wait_closed()
    return ours, theirs


async def sustained_rate(tmp: Path, seconds: float) -> tuple[float, str]:
    best, note = 0.0, ""
    for rate in (1e3, 1e4, 1e5, 1e6, 2e6, 4e6):
        path = tmp / f"sustain-{int(rate)}.h5"
        try:
            written, took, reason = await malcolm_capture(path, rate, seconds)
        except Exception as e:  # lost samples, an overrun
            note = f"{rate:.0e}/s failed: {type(e).__name__}: {e}"[:80]
            break
        if reason not in ("Ok", "Disarmed") or written < rate * seconds:
            note = f"{rate:.0e}/s: END {written} {reason}"
            break
        if took > seconds * 1.1 + 0.5:  # nothing lost, but it fell behind
            note = f"{rate:.0e}/s: {written} samples took {took:.1f} s"
            break
        best = rate
        note = f"{written} samples in {took:.1f} s, END {reason}"
    return best, note


async def main(args: argparse.Namespace) -> list[Row]:
    tmp = Path(tempfile.mkdtemp(prefix="zebra2-bench-"))
    rows = []
    intro = median([await introspection_seconds(tmp) for _ in range(5)])
    rows.append(
        Row("introspect tier 2 -> 19 ready children", intro, "s", "<= 0.5 s", "-")
    )
    managed, plain = await poll_round_trips(args.polls, tmp)
    rows.append(
        Row(
            "*CHANGES? poll through the manager / bare socket",
            managed / plain,
            "x",
            "<= 1.5x",
            "-",
            f"{managed * 1e3:.3f} ms vs {plain * 1e3:.3f} ms",
        )
    )
    ours, theirs = [], []
    for i in range(3):
        n, s, _ = await malcolm_capture(tmp / f"m{i}.h5", args.rate, args.window)
        ours.append(n / s)
        n, s = await pandablocks_capture(tmp / f"p{i}.h5", args.rate, args.window)
        theirs.append(n / s)
    rows.append(
        Row(
            "capture to HDF5: malcolm / pandablocks write_hdf_files",
            median(ours) / median(theirs),
            "x",
            ">= 1.0x",
            "-",
            f"{median(ours):.4g} vs {median(theirs):.4g} samples/s"
            f" at {args.rate:.0e}/s",
        )
    )
    streams = await record_streams(args.rate, args.window)
    pairs = [await replay_capture(streams, tmp, i) for i in range(3)]
    ours_r = median([p[0] for p in pairs])
    theirs_r = median([p[1] for p in pairs])
    rows.append(
        Row(
            "  on one recorded stream, replayed at full speed",
            ours_r / theirs_r,
            "x",
            ">= 1.0x",
            "-",
            f"{ours_r:.4g} vs {theirs_r:.4g} samples/s",
        )
    )
    best, note = await sustained_rate(tmp, args.sustain)
    rows.append(
        Row(
            f"largest rate sustained {args.sustain:g} s, none lost",
            best,
            "samples/s",
            "-",
            "-",
            note,
        )
    )
    return rows


def parse(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--polls", type=int, default=300)
    parser.add_argument("--rate", type=float, default=1e6, help="triggers/s")
    parser.add_argument("--window", type=float, default=1.0, help="s armed")
    parser.add_argument("--sustain", type=float, default=10.0, help="s")
    parser.add_argument("--quick", action="store_true", help="small figures")
    args = parser.parse_args(argv)
    if args.quick:
        args.polls, args.rate, args.window, args.sustain = 30, 1e4, 0.2, 0.5
    return args


if __name__ == "__main__":
    arguments = parse()
    proc = start_sim()
    try:
        print(render(asyncio.run(main(arguments)), "targets: issue 11"))
    finally:
        stop_sim(proc)

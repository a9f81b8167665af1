"""The CPU a Channel Access operation costs this process, through a block and
through raw pyepics, against the simulated IOC:

    ../shared/tools/isolated .venv/bin/python -m benchmarks.ca_cost [--puts 400]

``benchmarks.ca`` compares wall times (issue 10's targets), which the IOC's
latency dominates; this compares what the same operations cost the
client's CPU (the process's user + system time over all its threads:
libca's, pyepics' callbacks, the asyncio loop), the figure issue 13's
configures pay on two shared cores:

- **put+readback**: a block attribute's put with completion and the read of
  its readback (``process.put`` of ``ADCore.DetectorDriver``'s
  ``exposure``) against raw pyepics ``caput(wait=True)`` plus ``caget`` of
  the readback, in alternating rounds: CPU per operation, the ratio;
- **monitor event**: CPU per event of a fast-changing PV (the IOC's
  ticker) reaching a block attribute's subscriber, against a raw pyepics
  callback on the same PV (each alone, over the same seconds).
"""

from __future__ import annotations

import argparse
import asyncio
import os
import resource
import time
from typing import Any

from benchmarks.table import Row, render

PREFIX = "CACOST"
SOURCE = "no target in issue 13: the CPU behind issue 10's wall ratios"


def cpu() -> float:
    """This process's CPU seconds so far (every thread)."""
    used = resource.getrusage(resource.RUSAGE_SELF)
    return used.ru_utime + used.ru_stime


async def connected(process: Any, mri: str, timeout: float = 30.0) -> None:
    """Wait until block ``mri``'s channels are connected (a process's
    start waits 5 s for them; CA may take longer to find a new IOC's names
    among many others)."""
    deadline = time.monotonic() + timeout
    while process.get([mri, "health", "value"]) != "OK":
        if time.monotonic() > deadline:
            health = process.get([mri, "health", "value"])
            raise RuntimeError(f"{mri} not connected in {timeout} s: {health}")
        await asyncio.sleep(0.05)


def raw_puts(n: int, prefix: str = PREFIX) -> float:
    """CPU seconds of ``n`` raw pyepics puts and readback gets."""
    import epics

    pv, rbv = f"{prefix}:CAM:Exposure", f"{prefix}:CAM:Exposure_RBV"
    epics.caget(rbv)
    began = cpu()
    for i in range(n):
        epics.caput(pv, 0.001 * (i % 100 + 1), wait=True)
        epics.caget(rbv, use_monitor=False)
    return cpu() - began


async def puts(n: int, rounds: int, prefix: str = PREFIX) -> tuple[float, float]:
    """CPU seconds per put+readback through a block and raw, alternated
    (the IOC of ``prefix``)."""
    from malcolm.config.build import build_definition
    from malcolm.core import Process

    process = Process("bench", channels={"ca": "pyepics"})
    build_definition(
        "ADCore.DetectorDriver", {"prefix": f"{prefix}:CAM"}, "DRV", process=process
    )
    await process.start()
    ours = raw = 0.0
    try:
        await connected(process, "DRV")
        for _ in range(rounds):
            raw += raw_puts(n, prefix)  # blocking: the loop waits meanwhile
            began = cpu()
            for i in range(n):
                await process.put(["DRV", "exposure"], 0.001 * (i % 100 + 1))
            ours += cpu() - began
    finally:
        await process.stop()
    return ours / (n * rounds), raw / (n * rounds)


async def events(seconds: float) -> tuple[float, float]:
    """CPU seconds per ticker event through a block's subscriber, and
    through a raw pyepics callback (each measured alone)."""
    import epics

    from malcolm.controllers.stateful import StatefulController
    from malcolm.core import Process
    from malcolm.parts.soft import CALongPart

    ticker, run = f"{PREFIX}:BENCH:Ticker", f"{PREFIX}:BENCH:Run"
    loop = asyncio.get_running_loop()
    if not await loop.run_in_executor(
        None, lambda: epics.PV(run).wait_for_connection(30)
    ):
        raise RuntimeError(f"{run} not connected in 30 s")
    await loop.run_in_executor(None, epics.caput, run, 1, True)
    await asyncio.sleep(0.3)  # ticking steadily
    try:
        counts = [0]

        def raw(**_: Any) -> None:
            counts[0] += 1

        pv = epics.PV(ticker, callback=raw, auto_monitor=True)
        if not pv.wait_for_connection(30):
            raise RuntimeError(f"{ticker} not connected in 30 s")
        await asyncio.sleep(0.3)
        counts[0], began = 0, cpu()
        await asyncio.sleep(seconds)
        raw_cost = (cpu() - began) / max(counts[0], 1)
        pv.clear_callbacks()
        pv.disconnect()

        process = Process("bench", channels={"ca": "pyepics"})
        process.add_controller(StatefulController("T", [CALongPart("n", rbv=ticker)]))
        await process.start()
        try:
            await connected(process, "T")
            seen = [0]
            process.subscribe(
                ["T", "n", "value"], lambda _: seen.__setitem__(0, seen[0] + 1)
            )
            await asyncio.sleep(0.3)
            seen[0], began = 0, cpu()
            await asyncio.sleep(seconds)
            ours = (cpu() - began) / max(seen[0], 1)
        finally:
            await process.stop()
    finally:
        await loop.run_in_executor(None, epics.caput, run, 0, True)
    return ours, raw_cost


def measure(n: int, rounds: int, seconds: float) -> list[Row]:
    from malcolm.sim.beamline_ioc import SimIOC, ca_environment

    os.environ.update(ca_environment())
    ioc = SimIOC(PREFIX, bench_blocks=1)
    ioc.start()
    try:
        put_ours, put_raw = asyncio.run(puts(n, rounds))
        event_ours, event_raw = asyncio.run(events(seconds))
    finally:
        ioc.stop()
    us = 1e6
    return [
        Row("put+readback CPU, block / raw pyepics", put_ours / put_raw, "x", "-",
            "-", f"block {put_ours * us:.0f} us, raw {put_raw * us:.0f} us"),
        Row("monitor event CPU, block / raw pyepics", event_ours / event_raw, "x",
            "-", "-", f"block {event_ours * us:.1f} us, raw {event_raw * us:.1f} us"),
    ]  # fmt: skip


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.ca_cost")
    parser.add_argument("--puts", type=int, default=400, help="puts per round")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=2.0)
    args = parser.parse_args(argv)
    started = time.perf_counter()
    rows = measure(args.puts, args.rounds, args.seconds)
    print(render(rows, SOURCE))
    print(f"({time.perf_counter() - started:.0f} s)")


if __name__ == "__main__":
    main()

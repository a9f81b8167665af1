"""Issue 10's Channel Access benchmarks, against the simulated IOC.

    ../shared/tools/isolated .venv/bin/python -m benchmarks.ca [--puts 500]

One IOC (``malcolm.sim.beamline_ioc`` with the benchmark records), one run:

- **connect**: 100 hardware blocks of 20 PVs each (10 ``ca.Double`` with
  ``rbv_suffix``) built from one definition and started (every channel
  connected, its control information and first value read): seconds,
  target <= 2 s;
- **put**: a block attribute put with completion followed by the read of its
  readback (``process.put``), against raw pyepics ``caput(wait=True)`` plus
  ``caget`` of the readback, on the same PV pair, in alternating rounds:
  the ratio of the medians, target <= 1.3x;
- **monitor**: updates per second of a fast-changing PV reaching a block
  attribute, against raw pyepics callbacks on the same PV over the same
  seconds: the ratio, target >= 0.8x.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import tempfile
import threading
import time
from pathlib import Path

from benchmarks.table import Row, median, render

PREFIX = "CABENCH"
BLOCKS = 100
PAIRS = 10


def write_definition(folder: Path) -> None:
    (folder / "bench").mkdir(parents=True, exist_ok=True)
    (folder / "bench" / "Pairs.yaml").write_text(
        "init.String:\n    name: prefix\n    required: true\n\n"
        + "".join(
            f"ca.Double:\n    name: a{i}\n    pv: {{prefix}}:A{i}\n"
            "    rbv_suffix: _RBV\n    writeable: true\n\n"
            for i in range(PAIRS)
        )
    )


async def connect_blocks(search: Path) -> tuple[float, object]:
    from malcolm.config.build import build_definition
    from malcolm.core import Process

    process = Process("bench", channels={"ca": "pyepics"})
    for b in range(BLOCKS):
        values = {"prefix": f"{PREFIX}:B{b}"}
        build_definition("bench.Pairs", values, f"B{b}", [search], process=process)
    began = time.perf_counter()
    await process.start()
    took = time.perf_counter() - began
    unhealthy = [m for m in process.mris if process.get_block(m).health.value != "OK"]
    if unhealthy:
        raise RuntimeError(f"{len(unhealthy)} blocks not connected: {unhealthy[:3]}")
    await process.stop()
    return took, process


def raw_puts(n: int) -> list[float]:
    import epics

    pv, rbv = f"{PREFIX}:CAM:Exposure", f"{PREFIX}:CAM:Exposure_RBV"
    epics.caget(rbv)
    times = []
    for i in range(n):
        value = 0.001 * (i % 100 + 1)
        began = time.perf_counter()
        epics.caput(pv, value, wait=True)
        got = epics.caget(rbv, use_monitor=False)
        times.append(time.perf_counter() - began)
        assert abs(got - value) < 1e-9, (got, value)
    return times


async def puts(n: int, rounds: int = 5) -> tuple[list[float], list[float]]:
    """Seconds of each put+readback through a block and raw, in alternating
    rounds of ``n`` each (so a change of the machine's load hits both)."""
    from malcolm.config.build import build_definition
    from malcolm.core import Process

    process = Process("bench", channels={"ca": "pyepics"})
    build_definition(
        "ADCore.DetectorDriver", {"prefix": f"{PREFIX}:CAM"}, "DRV", process=process
    )
    await process.start()
    block = process.get_block("DRV")
    ours: list[float] = []
    raw: list[float] = []
    for _ in range(rounds):
        raw += raw_puts(n)  # blocking calls: the loop waits meanwhile
        for i in range(n):
            value = 0.001 * (i % 100 + 1)
            began = time.perf_counter()
            await process.put(["DRV", "exposure"], value)
            ours.append(time.perf_counter() - began)
            assert block.exposure.value == value
    await process.stop()
    return ours, raw


async def monitor_rates(seconds: float) -> tuple[float, float]:
    """Updates/s of the ticker through a block attribute and raw callbacks,
    counted over the same interval."""
    import epics

    from malcolm.controllers.stateful import StatefulController
    from malcolm.core import Process
    from malcolm.parts.soft import CALongPart

    ticker = f"{PREFIX}:BENCH:Ticker"
    process = Process("bench", channels={"ca": "pyepics"})
    process.add_controller(StatefulController("T", [CALongPart("n", rbv=ticker)]))
    await process.start()
    counts = {"raw": 0, "block": 0}
    counting = threading.Event()

    def raw(**_: object) -> None:
        if counting.is_set():
            counts["raw"] += 1

    def block(_: object) -> None:
        if counting.is_set():
            counts["block"] += 1

    pv = epics.PV(ticker, callback=raw, auto_monitor=True)
    pv.wait_for_connection(5)
    process.subscribe(["T", "n", "value"], block)
    loop = asyncio.get_running_loop()
    await loop.run_in_executor(None, epics.caput, f"{PREFIX}:BENCH:Run", 1, True)
    await asyncio.sleep(0.5)  # running steadily
    counting.set()
    began = time.perf_counter()
    await asyncio.sleep(seconds)
    counting.clear()
    took = time.perf_counter() - began
    await loop.run_in_executor(None, epics.caput, f"{PREFIX}:BENCH:Run", 0, True)
    pv.clear_callbacks()
    pv.disconnect()
    await process.stop()
    return counts["block"] / took, counts["raw"] / took


def main() -> None:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.ca")
    parser.add_argument("--puts", type=int, default=500)
    parser.add_argument("--seconds", type=float, default=3.0)
    args = parser.parse_args()

    from malcolm.sim.beamline_ioc import SimIOC, ca_environment

    os.environ.update(ca_environment())
    ioc = SimIOC(PREFIX, bench_blocks=BLOCKS)
    ioc.start()
    try:
        with tempfile.TemporaryDirectory() as tmp:
            search = Path(tmp)
            write_definition(search)
            connect, _ = asyncio.run(connect_blocks(search))
            ours, raw = asyncio.run(puts(args.puts // 5))
            through_block, through_raw = asyncio.run(monitor_rates(args.seconds))
    finally:
        ioc.stop()
    raw_put = median(raw)
    rows = [
        Row(
            f"{BLOCKS} blocks x {2 * PAIRS} PVs connect",
            connect,
            "s",
            "<= 2 s",
            "-",
        ),
        Row(
            "put+readback, block / raw pyepics",
            median(ours) / raw_put,
            "x",
            "<= 1.3x",
            "-",
            f"block {median(ours) * 1e3:.3f} ms, raw {raw_put * 1e3:.3f} ms"
            " (issue: raw 0.7-0.9 ms)",
        ),
        Row(
            "monitor updates/s, block / raw pyepics",
            through_block / through_raw,
            "x",
            ">= 0.8x",
            "-",
            f"block {through_block:.0f}/s, raw {through_raw:.0f}/s"
            " (issue: raw 6.5-8.2k/s)",
        ),
    ]
    print(render(rows, "targets: issue 10"))


if __name__ == "__main__":
    main()

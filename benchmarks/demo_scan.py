"""Issue 8's demo scan benchmarks: overhead per point, and the loop kept free.

    .venv/bin/python -m benchmarks.demo_scan [--points 2000] [--grid 1000]

- overhead per point of the demo scan (SCAN: two simulated detectors, two
  motors) at its minimum exposure: (run time - the points' total duration)
  / points, median of three scans. The minimum exposure is taken as 1 ms
  (MIN_EXPOSURE): the scan's own work per point (also printed: the same scan
  at 1 us a point, where the work is all there is) must fit in it, or the
  overhead measured is that work. Beside it, what sleeping a duration per
  point (as the simulated parts did before) costs on the same run.
- the longest stall of the loop while the demo SCAN is configured (its
  points computed in a worker thread), measured by a ticker on the loop (a
  1 ms sleep in a loop: the longest gap between its wake-ups, less the
  1 ms), for a ``--grid`` x ``--grid`` snake grid, a spiral of as many
  points, and the grid with a circular region (which evaluates the joined
  dimension when built); beside each, the stall of computing the same
  points on the loop, as configure did before.
"""

from __future__ import annotations

import argparse
import asyncio
import math
import time
from typing import Any

from benchmarks.table import Row, median, render
from malcolm.core import Process
from malcolm.demo import demo_process
from malcolm.scan import gda, scan_points

MIN_EXPOSURE = 0.001  # seconds a point
TICK = 0.001


def grid(points: int, duration: float) -> dict[str, Any]:
    """A snake grid of about ``points`` points as GDA sends it."""
    ny = max(1, int(math.sqrt(points)))
    nx = max(1, points // ny)
    return gda.compound(
        gda.line("y", ny), gda.line("x", nx, alternate=True), duration=duration
    )


def spiral(points: int, duration: float) -> dict[str, Any]:
    """A spiral of about ``points`` points over x and y."""
    radius = math.sqrt((points - 0.5) / math.pi)
    return gda.compound(gda.spiral("x", "y", radius), duration=duration)


def circled_grid(points: int, duration: float) -> dict[str, Any]:
    """:func:`grid` with the points outside a circle excluded."""
    excluder = {
        "typeid": "scanpointgenerator:excluder/ROIExcluder:1.0",
        "axes": ["x", "y"],
        "rois": [
            {
                "typeid": "scanpointgenerator:roi/CircularROI:1.0",
                "centre": [0.5, 0.5],
                "radius": 0.5,
            }
        ],
    }
    return {**grid(points, duration), "excluders": [excluder]}


SHAPES = {"snake grid": grid, "spiral": spiral, "grid, circle region": circled_grid}


async def started() -> Process:
    process = demo_process()
    await process.start()
    return process


async def run_scan(process: Process, generator: dict[str, Any]) -> tuple[int, float]:
    """Configure SCAN, run it to the end: (points, seconds the runs took)."""
    await process.post(["SCAN", "configure"], {"generator": generator})
    total = process.get(["SCAN", "totalSteps", "value"])
    start = time.perf_counter()
    while process.get(["SCAN", "state", "value"]) != "Finished":
        await process.post(["SCAN", "run"])
    return total, time.perf_counter() - start


async def overhead_per_point(points: int, duration: float) -> float:
    """Seconds a point of the demo scan takes beyond its duration."""
    process = await started()
    try:
        n, elapsed = await run_scan(process, grid(points, duration))
        return (elapsed - n * duration) / n
    finally:
        await process.stop()


async def sleep_per_point(points: int, duration: float) -> float:
    """What a point costs beyond its duration when each sleeps its duration."""
    start = time.perf_counter()
    for _ in range(points):
        await asyncio.sleep(duration)
    return (time.perf_counter() - start - points * duration) / points


class Ticker:
    """A task on the loop that notes the longest gap between its wake-ups."""

    def __init__(self) -> None:
        self.worst = 0.0
        self._task: asyncio.Task[None] | None = None

    async def _tick(self) -> None:
        last = time.perf_counter()
        while True:
            await asyncio.sleep(TICK)
            now = time.perf_counter()
            self.worst = max(self.worst, now - last - TICK)
            last = now

    async def __aenter__(self) -> Ticker:
        self._task = asyncio.ensure_future(self._tick())
        await asyncio.sleep(TICK * 3)  # ticking before the work starts
        self.worst = 0.0
        return self

    async def __aexit__(self, *exc: object) -> None:
        assert self._task is not None
        self._task.cancel()
        try:
            await self._task
        except asyncio.CancelledError:
            pass


async def configure_stall(generator: dict[str, Any]) -> tuple[float, float]:
    """(longest loop stall, seconds) of configuring SCAN with ``generator``."""
    process = await started()
    try:
        async with Ticker() as ticker:
            start = time.perf_counter()
            await process.post(["SCAN", "configure"], {"generator": generator})
            elapsed = time.perf_counter() - start
        return ticker.worst, elapsed
    finally:
        await process.stop()


async def on_loop_stall(generator: dict[str, Any]) -> float:
    """Longest loop stall of computing ``generator``'s points on the loop."""
    async with Ticker() as ticker:
        await asyncio.sleep(0)
        scan_points(generator)
        await asyncio.sleep(TICK * 3)
    return ticker.worst


async def measure(points: int, size: int, repeats: int = 3) -> list[Row]:
    # each repeat a slightly different scan, so none finds its points kept
    durations = [MIN_EXPOSURE * (1 + i * 1e-6) for i in range(repeats)]
    overhead = median([await overhead_per_point(points, d) for d in durations])
    work = median(
        [await overhead_per_point(points, 1e-6 * (1 + i)) for i in range(repeats)]
    )
    slept = median([await sleep_per_point(points, d) for d in durations])
    stalls = []
    for shape, make in SHAPES.items():
        # a different scan each time, so that none finds its points kept
        found = [
            await configure_stall(make(size * size, 0.1 + i * 1e-6))
            for i in range(repeats)
        ]
        before = await on_loop_stall(make(size * size, 0.2))
        stalls.append((shape, found, before))
    ms = 1e3
    rows = [
        Row(
            f"demo scan overhead/point at {MIN_EXPOSURE * ms:g} ms",
            overhead * ms,
            "ms",
            "<= 0.05 ms",
            "-",
            f"{points} points; was 0.5 ms",
        ),
        Row(
            "  one asyncio.sleep(duration) a point",
            slept * ms,
            "ms",
            "-",
            "-",
            "how the parts paced before",
        ),
        Row(
            "  demo scan work/point (1 us exposure)",
            work * ms,
            "ms",
            "-",
            "-",
            "must fit in the exposure",
        ),
    ]
    for shape, found, before in stalls:
        rows.append(
            Row(
                f"loop stall, configure {size}x{size} {shape}",
                median([s for s, _ in found]) * ms,
                "ms",
                "<= 50 ms",
                "-",
                f"configure took {median([t for _, t in found]):.3g} s",
            )
        )
        rows.append(
            Row(
                "  same points computed on the loop",
                before * ms,
                "ms",
                "-",
                "-",
                "as configure did before",
            )
        )
    return rows


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=2000)
    parser.add_argument("--grid", type=int, default=1000)
    args = parser.parse_args(argv)
    print(render(asyncio.run(measure(args.points, args.grid))))


if __name__ == "__main__":
    main()

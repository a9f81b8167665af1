"""Where a beamline run's time goes: a timeline of one run.

    ../shared/tools/isolated .venv/bin/python -m benchmarks.beamline_timeline \
        [--points 1000] [--exposure 0.0005] [--mri BENCH:SCAN]

Builds the simulated beamline as :mod:`benchmarks.beamline` does, configures
a snake grid (``--shape spiral``: a spiral, no turnarounds) of ``--points``
at ``--exposure`` (after ``validate``), runs it
once and prints, in ms from the run's start, when each block's state and
the counters a run follows changed, the motion's own time (its profile's
run-up, points and turnarounds) and how many monitor updates each child
attribute brought during the run (the per-point work malcolm receives).
"""

from __future__ import annotations

import argparse
import asyncio
import os
import tempfile
import time
from collections import Counter
from typing import Any

from benchmarks.beamline import (
    PREFIX,
    beamline_process,
    grid,
    smallest_exposure,
    spiral,
)

WATCHED = {
    "SCAN": ("state",),
    "DET": ("state", "completedSteps"),
    "MOTORS": ("state", "completedSteps"),
    "ZEBRA": ("state", "completedSteps"),
    "MOTORS:traj": ("executeState", "pointsScanned"),
    "DET:HDF": ("capture", "numCaptured"),
    "DET:DRV": ("detectorState",),
}


async def timeline(points: int, want: float, mri: str, shape: str) -> None:
    from malcolm.beamline import BEAMLINE_PROCESS_FILE

    async with beamline_process(BEAMLINE_PROCESS_FILE) as process:
        with tempfile.TemporaryDirectory() as file_dir:
            await one_run(process, points, want, mri, file_dir, shape)


async def one_run(
    process: Any, points: int, want: float, mri: str, d: str, shape: str
) -> None:
    exposure = await smallest_exposure(process, f"{PREFIX}:SCAN", want)
    ny = max(1, int(points**0.5))
    nx = max(1, points // ny)
    scan = grid(ny, nx, exposure) if shape == "grid" else spiral(points, exposure)
    args = {"axesToMove": ["x", "y"], "fileDir": d}
    await process.post([mri, "configure"], {"generator": scan, **args})
    n = int(process.get([mri, "totalSteps", "value"]))
    profile = process.get_controller(f"{PREFIX}:MOTORS").parts["trajectory"].profile
    motion = float(profile.times.sum()) / 1e6 if profile is not None else 0.0
    events: list[tuple[float, str]] = []
    counts: Counter[str] = Counter()
    t0 = [0.0]

    def watcher(name: str) -> Any:
        def on(value: Any) -> None:
            counts[name] += 1
            events.append((time.perf_counter() - t0[0], f"{name} = {value}"))

        return on

    # every attribute of the children: how many updates each brought
    subs = []
    for block_name in ("DET:DRV", "DET:POS", "DET:HDF", "MOTORS:traj", "MOTORS:a",
                       "MOTORS:b"):  # fmt: skip
        block = process.get_block(f"{PREFIX}:{block_name}")
        for field in block:
            if hasattr(block[field], "value") and not (
                block_name in WATCHED and field in WATCHED[block_name]
            ):
                subs.append(
                    process.subscribe(
                        [f"{PREFIX}:{block_name}", field, "value"],
                        lambda _v, n=f"{block_name}.{field}": counts.update([n]),
                        delta=False,
                    )
                )
    for block_name, fields in WATCHED.items():
        for field in fields:
            subs.append(
                process.subscribe(
                    [f"{PREFIX}:{block_name}", field, "value"],
                    watcher(f"{block_name}.{field}"),
                    delta=False,
                )
            )
    await asyncio.sleep(0.2)
    events.clear()
    counts.clear()
    t0[0] = time.perf_counter()
    await process.post([mri, "run"])
    took = time.perf_counter() - t0[0]
    for sub in subs:
        process.unsubscribe(sub)
    last: dict[str, float] = {}
    for at, what in events:
        key = what.split(" = ")[0]
        if key.endswith(("pointsScanned", "numCaptured", "completedSteps")):
            last[key] = at  # only the last of the counters
            continue
        print(f"{at * 1e3:9.1f} ms  {what}")
    for key, at in sorted(last.items(), key=lambda kv: kv[1]):
        print(f"{at * 1e3:9.1f} ms  {key} (last update)")
    print(
        f"run {took * 1e3:.1f} ms for {n} points at {exposure * 1e3:g} ms; the"
        f" motion's profile {motion * 1e3:.1f} ms; beyond it"
        f" {(took - motion) * 1e3:.1f} ms ({(took - motion) / n * 1e3:.3f} ms/point)"
    )
    print("monitor updates during the run (per point):")
    for name, count in counts.most_common():
        print(f"  {name:32} {count:6}  {count / n:.2f}")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=1000)
    parser.add_argument("--exposure", type=float, default=0.0005)
    parser.add_argument("--mri", default=f"{PREFIX}:SCAN")
    parser.add_argument(
        "--shape",
        choices=("grid", "spiral"),
        default="grid",
        help="a snake grid (as benchmarks.beamline) or a spiral (no turnarounds:"
        " the points back to back, the sustained rate)",
    )
    args = parser.parse_args(argv)
    from malcolm.sim.beamline_ioc import ca_environment

    os.environ.update(ca_environment())
    asyncio.run(timeline(args.points, args.exposure, args.mri, args.shape))


if __name__ == "__main__":
    main()

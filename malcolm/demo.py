"""The demo process: simulated hardware that needs nothing installed.

Blocks: ``HELLO`` (greet, error), ``COUNTER`` (counter, delta, zero,
increment), motors ``MOTOR:X`` and ``MOTOR:Y``, runnable detectors ``DET1``
and ``DET2`` that take the scan's duration per point, and ``SCAN``, which
coordinates both detectors and the motors.
"""

from __future__ import annotations

import asyncio
import sys
from collections.abc import Callable
from typing import Any, TextIO

from malcolm.controllers.runnable import RunnableController
from malcolm.controllers.stateful import StatefulController
from malcolm.core import Process
from malcolm.parts.demo import (
    CounterPart,
    HelloPart,
    MotorMovePart,
    RunnableChildPart,
    SimDetectorPart,
    SimMotorPart,
)


def demo_process(prefix: str = "") -> Process:
    """Build (not start) the demo process; ``prefix`` goes before every mri."""
    p = Process("demo")
    p.add_controller(
        StatefulController(f"{prefix}HELLO", [HelloPart("hello")], "Says hello")
    )
    p.add_controller(
        StatefulController(f"{prefix}COUNTER", [CounterPart("counter")], "Counts")
    )
    for axis in ("X", "Y"):
        p.add_controller(
            StatefulController(
                f"{prefix}MOTOR:{axis}", [SimMotorPart("motor")], f"Motor {axis}"
            )
        )
    for det in ("DET1", "DET2"):
        p.add_controller(
            RunnableController(
                f"{prefix}{det}", [SimDetectorPart("detector")], "Simulated detector"
            )
        )
    p.add_controller(
        RunnableController(
            f"{prefix}SCAN",
            [
                RunnableChildPart("DET1", f"{prefix}DET1"),
                RunnableChildPart("DET2", f"{prefix}DET2"),
                MotorMovePart("x", f"{prefix}MOTOR:X", "x"),
                MotorMovePart("y", f"{prefix}MOTOR:Y", "y"),
            ],
            "Scans the motors while both detectors take frames",
        )
    )
    return p


def demo_generator(
    ny: int = 3, nx: int = 4, duration: float = 0.05, snake: bool = True
) -> dict[str, Any]:
    """A y/x grid as GDA sends it (a CompoundGenerator dict)."""

    def line(axis: str, size: int, alternate: bool) -> dict[str, Any]:
        return {
            "typeid": "scanpointgenerator:generator/LineGenerator:1.0",
            "axes": [axis],
            "units": ["mm"],
            "start": [0.0],
            "stop": [1.0],
            "size": size,
            "alternate": alternate,
        }

    return {
        "typeid": "scanpointgenerator:generator/CompoundGenerator:1.0",
        "generators": [line("y", ny, False), line("x", nx, snake)],
        "excluders": [],
        "mutators": [],
        "duration": duration,
        "continuous": True,
        "delay_after": 0.0,
    }


def progress_bar(done: int, total: int, width: int = 40) -> str:
    filled = width * done // total if total else width
    return f"[{'#' * filled}{'.' * (width - filled)}] {done}/{total}"


async def run_demo_scan(
    process: Process,
    generator: dict[str, Any] | None = None,
    out: TextIO = sys.stdout,
    on_progress: Callable[[int, int], None] | None = None,
) -> None:
    """Configure and run SCAN to the end, drawing completedSteps/totalSteps."""
    scan = next(m for m in process.mris if m.endswith("SCAN"))
    block = process.get_block(scan)

    def draw(done: int) -> None:
        total = block.totalSteps.value
        out.write(f"\r{scan} {progress_bar(done, total)}")
        out.flush()
        if on_progress:
            on_progress(done, total)

    await process.post(
        [scan, "configure"], {"generator": generator or demo_generator()}
    )
    sub = process.subscribe([scan, "completedSteps", "value"], draw, delta=False)
    try:
        while block.state.value != "Finished":
            await process.post([scan, "run"])
    finally:
        process.unsubscribe(sub)
        out.write(f"\n{scan} {block.state.value}\n")


def describe(process: Process) -> str:
    lines = []
    for mri in process.mris:
        block = process.get_block(mri)
        fields = ", ".join(n for n in block if n not in ("health", "state"))
        lines.append(f"  {mri:<10} {block.state.value:<8} {fields}")
    return "\n".join(lines)


async def serve_demo(scan: bool, out: TextIO = sys.stdout) -> int:
    process = demo_process()
    await process.start()
    out.write("malcolm demo: blocks (mri, state, fields)\n" + describe(process) + "\n")
    try:
        if scan:
            await run_demo_scan(process, out=out)
            return 0
        out.write("Serving until interrupted (Ctrl-C).\n")
        await asyncio.Event().wait()
        return 0
    finally:
        await process.stop()

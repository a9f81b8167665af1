"""The demo process: simulated hardware that needs nothing installed.

Built from the YAML definitions in ``malcolm/blocks/demo/``.
Blocks: ``HELLO`` (greet, error), ``COUNTER`` (counter, delta, zero,
increment), motors ``MOTOR:X`` and ``MOTOR:Y``, runnable detectors ``DET1``
and ``DET2`` that take the scan's duration per point, and ``SCAN``, which
coordinates both detectors and the motors.
"""

from __future__ import annotations

import asyncio
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any, TextIO

from malcolm.core import Process
from malcolm.scan import gda

#: The demo's process file; copy it to start your own.
DEMO_PROCESS_FILE = Path(__file__).resolve().parent / "blocks" / "demo" / "process.yaml"


def demo_process(prefix: str = "") -> Process:
    """Build (not start) the demo process from ``blocks/demo/process.yaml``;
    ``prefix`` (the file's ``prefix`` define) goes before every mri."""
    from malcolm.config.build import build_process

    return build_process(
        DEMO_PROCESS_FILE, process=Process("demo"), defines={"prefix": prefix}
    )


def demo_generator(
    ny: int = 3, nx: int = 4, duration: float = 0.05, snake: bool = True
) -> dict[str, Any]:
    """A y/x grid as GDA sends it (a CompoundGenerator dict)."""
    return gda.compound(
        gda.line("y", ny), gda.line("x", nx, alternate=snake), duration=duration
    )


def progress_bar(done: int, total: int, width: int = 40) -> str:
    filled = width * done // total if total else width
    return f"[{'#' * filled}{'.' * (width - filled)}] {done}/{total}"


async def run_demo_scan(
    process: Process,
    generator: dict[str, Any] | None = None,
    out: TextIO | None = None,
    on_progress: Callable[[int, int], None] | None = None,
) -> None:
    """Configure and run SCAN to the end, drawing completedSteps/totalSteps."""
    stream = out or sys.stdout
    scan = next(m for m in process.mris if m.endswith("SCAN"))
    block = process.get_block(scan)

    def draw(done: int) -> None:
        total = block.totalSteps.value
        stream.write(f"\r{scan} {progress_bar(done, total)}")
        stream.flush()
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
        stream.write(f"\n{scan} {block.state.value}\n")


def describe(process: Process) -> str:
    lines = []
    for mri in process.mris:
        block = process.get_block(mri)
        fields = ", ".join(n for n in block if n not in ("health", "state"))
        lines.append(f"  {mri:<10} {block.state.value:<8} {fields}")
    return "\n".join(lines)


REACH = """\
How to reach the blocks:
  from Python (in this process or your own):
      from malcolm.demo import demo_process
      from malcolm.embed import start_process
      with start_process(demo_process()) as p:
          print(p.block("HELLO").greet(name="me"))
          p.block("COUNTER").counter.put(3)
  or copy the process file and serve it:  malcolm serve {process_file}
"""


async def serve_demo(scan: bool, out: TextIO | None = None) -> int:
    # sys.stdout is read per call (not as a default) so redirections apply
    out = out or sys.stdout
    process = demo_process()
    await process.start()
    out.write("malcolm demo: blocks (mri, state, fields)\n" + describe(process) + "\n")
    try:
        if scan:
            await run_demo_scan(process, out=out)
            return 0
        out.write(REACH.format(process_file=DEMO_PROCESS_FILE))
        out.write("Serving until interrupted (Ctrl-C).\n")
        await asyncio.Event().wait()
        return 0
    finally:
        await process.stop()

"""The demo process: simulated hardware that needs nothing installed.

Built from the YAML definitions in ``malcolm/blocks/demo/``.
Blocks: ``HELLO`` (greet, error), ``COUNTER`` (counter, delta, zero,
increment), motors ``MOTOR:X`` and ``MOTOR:Y``, runnable detectors ``DET1``
and ``DET2`` that take the scan's duration per point, and ``SCAN``, which
coordinates both detectors and the motors.
"""

from __future__ import annotations

import asyncio
import contextlib
import signal
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, TextIO

from malcolm.core import MalcolmError, Process, long_lived

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
    from malcolm.scan import gda

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
    """Configure and run SCAN to the end, drawing completedSteps/totalSteps,
    then a line ``SCAN Finished``. A call that fails raises its error."""
    stream = out or sys.stdout
    scan = _scan_mri(process)
    block = process.get_block(scan)
    model = process.get_controller(scan).model

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
        while not model.is_state(block.state.value, "finished"):
            await process.post([scan, "run"])
    finally:
        process.unsubscribe(sub)
        stream.write("\n")
    stream.write(f"{scan} {block.state.value}\n")


def _scan_mri(process: Process) -> str:
    return next(m for m in process.mris if m.endswith("SCAN"))


async def abort_demo_scan(process: Process) -> str:
    """Abort SCAN and wait until the abort has ended; its state then."""
    scan = _scan_mri(process)
    try:
        await process.post([scan, "abort"])
    except MalcolmError:  # not allowed from here (e.g. Fault): leave it be
        pass
    return str(process.get_block(scan).state.value)


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


async def serve_demo(
    scan: bool,
    out: TextIO | None = None,
    err: TextIO | None = None,
    signals: Sequence[int] = (signal.SIGINT, signal.SIGTERM),
    generator: dict[str, Any] | None = None,
    freeze: bool = False,
    pva_port: int = 0,
    zebra2: bool = False,
    web_port: int | None = None,
) -> int:
    """Serve the demo process until one of ``signals``, or run its scan
    (``generator``, by default :func:`demo_generator`'s grid). ``freeze``
    builds and starts it under :func:`malcolm.core.long_lived` (the command
    line does: its blocks live until the program ends). ``pva_port`` (if not
    0) serves the blocks over pvAccess on that port, from before they start.
    ``zebra2`` adds a simulated Zebra2 box with its manager (``ZEBRA2``) and
    capture block (:mod:`malcolm.parts.zebra2_demo`). ``web_port``
    (not 0 or None) serves it on the web too (docs/web.md).

    The exit status: 0 once the scan has Finished (``scan``), or when serving
    is stopped by a signal; ``128 + signal`` (130 for SIGINT, 143 for
    SIGTERM) when a signal interrupts the scan, which is aborted first (the
    state it reached is reported on ``err``). The process is always stopped.
    """
    # sys.stdout is read per call (not as a default) so redirections apply
    out = out or sys.stdout
    err = err or sys.stderr
    loop = asyncio.get_running_loop()
    received: list[int] = []
    stop = asyncio.Event()

    def on_signal(sig: int) -> None:
        received.append(sig)
        stop.set()

    for sig in signals:
        loop.add_signal_handler(sig, on_signal, sig)
    pva = box = web = process = None
    try:
        with long_lived() if freeze else contextlib.nullcontext():
            process = demo_process()
            if pva_port:
                from malcolm.io.pva import start_pva_server
                from malcolm.io.pva.client_blocklist import add_block_list

                pva = await start_pva_server(process, pva_port)
                add_block_list(process)  # for malcolm ls (docs/pva-client.md)
            if zebra2:
                from malcolm.parts.zebra2_demo import start_demo_zebra2

                box = await start_demo_zebra2(process)
                out.write(
                    f"malcolm demo: simulated Zebra2 box: control {box.host}:"
                    f"{box.control_port}, data {box.host}:{box.data_port}\n"
                )
            await process.start()
        from malcolm.io.web.cli import start_if_asked

        web = await start_if_asked(process, web_port, "malcolm demo", out, err)
        if pva is not None:
            out.write(f"malcolm demo: pvAccess on {pva.address}\n")
        status = await _demo(process, scan, generator, stop, received, out, err)
    finally:
        # whatever was started is let go of, also when starting failed
        try:
            if web is not None:
                await web.close()
            if pva is not None:
                await pva.close()
            if process is not None:
                await process.stop()
            if box is not None:
                await box.close()
        finally:
            for sig in signals:
                loop.remove_signal_handler(sig)
    if received:
        err.write(f"malcolm demo: {signal.Signals(received[0]).name}: stopped\n")
    return status


async def _demo(
    process: Process,
    scan: bool,
    generator: dict[str, Any] | None,
    stop: asyncio.Event,
    received: list[int],
    out: TextIO,
    err: TextIO,
) -> int:
    if stop.is_set():  # signalled while starting
        return 128 + received[0] if scan else 0
    out.write("malcolm demo: blocks (mri, state, fields)\n" + describe(process) + "\n")
    if scan:
        return await _scan_until_signalled(process, generator, stop, received, out, err)
    out.write(REACH.format(process_file=DEMO_PROCESS_FILE))
    out.write("Serving until interrupted (Ctrl-C or SIGTERM).\n")
    out.flush()
    await stop.wait()
    return 0


async def _scan_until_signalled(
    process: Process,
    generator: dict[str, Any] | None,
    stop: asyncio.Event,
    received: list[int],
    out: TextIO,
    err: TextIO,
) -> int:
    scan = asyncio.ensure_future(run_demo_scan(process, generator, out=out))
    stopped = asyncio.ensure_future(stop.wait())
    await asyncio.wait({scan, stopped}, return_when=asyncio.FIRST_COMPLETED)
    if not stop.is_set():
        stopped.cancel()
        await scan  # raises what the scan raised
        return 0
    state = await abort_demo_scan(process)
    try:
        await scan
    except MalcolmError:  # the pending call ends when the scan is aborted
        pass
    name = signal.Signals(received[0]).name
    out.write(f"{_scan_mri(process)} {state}\n")
    out.flush()
    err.write(f"malcolm demo: {name}: {_scan_mri(process)} {state}\n")
    err.flush()
    return 128 + received[0]

"""``malcolm beamline``: the simulated beamline, all three layers, served.

It starts the simulated beamline IOC (detector and motion controller over
Channel Access: :class:`~malcolm.sim.beamline_ioc.SimIOC`) and a simulated
Zebra2 box (``malcolm sim-zebra2`` on free ports) as subprocesses, builds
the process file ``malcolm/blocks/beamline/process.yaml`` (the hardware
blocks, the three device managers and the BeamlineManager ``<prefix>:SCAN``)
against them, serves it over pvAccess and the web, prints where everything
is, and runs until Ctrl-C or SIGTERM, when it stops the process and both
subprocesses. docs/beamline.md walks through a scan.
"""

from __future__ import annotations

import argparse
import os
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, TextIO

#: the beamline's process file; copy it to start your own
BEAMLINE_PROCESS_FILE = (
    Path(__file__).resolve().parent / "blocks" / "beamline" / "process.yaml"
)
HELP = "serve a simulated beamline: IOC, Zebra2, device managers and SCAN"
_ZEBRA_READY = re.compile(r"control (\S+):(\d+) data (\S+):(\d+)")


def add_beamline_manager(
    process: Any, devices: Mapping[str, Sequence[Any]], mri: str = "BL"
) -> None:
    """Add to ``process`` a BeamlineManager ``mri`` over the device blocks
    ``<mri>:DET``, ``<mri>:MOTORS`` and ``<mri>:ZEBRA``, each a
    RunnableController of the parts ``devices`` gives for ``DET``,
    ``MOTORS`` and ``ZEBRA``: the co-ordination layer without hardware (for
    tests of one's own device parts, and benchmarks.coordination)."""
    from malcolm.config.build import build_definition
    from malcolm.controllers.runnable import RunnableController

    for name, parts in devices.items():
        process.add_controller(RunnableController(f"{mri}:{name}", list(parts)))
    build_definition(
        "beamline.BeamlineManager",
        {"det": f"{mri}:DET", "motor": f"{mri}:MOTORS", "zebra": f"{mri}:ZEBRA"},
        mri=mri,
        process=process,
    )


class SimZebra2:
    """``malcolm sim-zebra2`` in a subprocess on free ports of ``host``."""

    def __init__(self, host: str = "127.0.0.1") -> None:
        self.host = host
        self.control_port = 0
        self.data_port = 0
        self.process: subprocess.Popen[str] | None = None
        self.output: list[str] = []

    def start(self, timeout: float = 30.0) -> None:
        """Start the box; raises RuntimeError if it does not serve in time."""
        self.process = subprocess.Popen(
            [sys.executable, "-m", "malcolm", "sim-zebra2", "--host", self.host,
             "--control-port", "0", "--data-port", "0"],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            env={**os.environ, "PYTHONUNBUFFERED": "1"},
        )  # fmt: skip
        ready = threading.Event()
        threading.Thread(target=self._read, args=(ready,), daemon=True).start()
        deadline = time.monotonic() + timeout
        while not ready.wait(0.05):
            if self.process.poll() is not None or time.monotonic() > deadline:
                self.stop()
                raise RuntimeError(
                    "simulated Zebra2 did not start:\n" + "".join(self.output)
                )

    def _read(self, ready: threading.Event) -> None:
        assert self.process is not None and self.process.stdout is not None
        for line in self.process.stdout:
            self.output.append(line)
            found = _ZEBRA_READY.search(line)
            if found and not ready.is_set():
                self.control_port = int(found.group(2))
                self.data_port = int(found.group(4))
                ready.set()

    @property
    def alive(self) -> bool:
        return self.process is not None and self.process.poll() is None

    def kill(self) -> None:
        """End the box at once (SIGKILL), as a power cut would."""
        if self.alive:
            assert self.process is not None
            self.process.kill()
        self._reap()

    def stop(self) -> None:
        """SIGTERM the box and wait (SIGKILL if it does not end)."""
        if self.alive:
            assert self.process is not None
            self.process.terminate()
            try:
                self.process.wait(10)
            except subprocess.TimeoutExpired:
                self.process.kill()
        self._reap()

    def _reap(self) -> None:
        if self.process is not None:
            self.process.wait()
            if self.process.stdout is not None:
                self.process.stdout.close()


def beamline_defines(prefix: str, zebra: SimZebra2, file_dir: str) -> dict[str, Any]:
    """The process file's ``define`` values for these simulators."""
    return {
        "prefix": prefix,
        "zebra_host": zebra.host,
        "zebra_control_port": zebra.control_port,
        "zebra_data_port": zebra.data_port,
        "file_dir": file_dir,
    }


def build_beamline(process_file: Path, defines: dict[str, Any]) -> Any:
    """Build (not start) the beamline process from ``process_file``."""
    from malcolm.config.build import build_process
    from malcolm.core import Process

    return build_process(
        process_file,
        process=Process("beamline", channels={"ca": "pyepics"}),
        defines=defines,
    )


def describe(process: Any, pva: str, web: str, out: TextIO) -> None:
    """Print the blocks and where they are served."""
    out.write("malcolm beamline: blocks (mri, state)\n")
    for mri in process.mris:
        out.write(f"  {mri:<28} {process.get_block(mri).state.value}\n")
    out.write(f"malcolm beamline: pvAccess on {pva}; web {web}\n")
    out.flush()


def cmd_beamline(args: argparse.Namespace) -> int:
    """Start the simulators, serve the beamline until signalled, stop all."""
    import logging

    from malcolm.config import ConfigError
    from malcolm.core import long_lived
    from malcolm.embed import serve
    from malcolm.embed.loop import run as run_loop
    from malcolm.sim.beamline_ioc import SimIOC, ca_environment

    logging.basicConfig(
        level=logging.INFO, stream=sys.stderr, format="%(asctime)s %(message)s"
    )
    logging.getLogger("transitions").setLevel(logging.WARNING)
    # before pyepics makes its context: the IOC on this host only
    os.environ.update(ca_environment(args.ca_port))
    file_dir = str(Path(args.file_dir).resolve()) if args.file_dir else ""
    if file_dir:
        Path(file_dir).mkdir(parents=True, exist_ok=True)
    ioc = SimIOC(args.prefix, env=ca_environment(args.ca_port))
    zebra = SimZebra2()
    try:
        # SIGTERM while starting: stop the subprocesses as Ctrl-C would
        signal.signal(signal.SIGTERM, _raise_interrupt)
        ioc.start()
        assert ioc.process is not None
        print(
            f"malcolm beamline: simulated IOC, prefix {args.prefix}"
            f" (pid {ioc.process.pid})",
            flush=True,
        )
        zebra.start()
        print(
            f"malcolm beamline: simulated Zebra2: control {zebra.host}:"
            f"{zebra.control_port}, data {zebra.host}:{zebra.data_port}"
            f" (pid {zebra.process.pid if zebra.process else '-'})",
            flush=True,
        )
        defines = beamline_defines(args.prefix, zebra, file_dir)
        try:
            with long_lived():
                process = build_beamline(Path(args.process), defines)
        except ConfigError as e:
            for problem in e.problems:
                print(problem, file=sys.stderr)
            print("malcolm beamline: nothing started", file=sys.stderr)
            return 1
        signal.signal(signal.SIGTERM, signal.SIG_DFL)

        def ready(p: Any) -> None:
            web = f"http://localhost:{args.web_port}/" if args.web_port else "off"
            pva = f"0.0.0.0:{args.pva_port}" if args.pva_port else "off"
            describe(p, pva, web, sys.stdout)
            print(
                f"Scan with {args.prefix}:SCAN (docs/beamline.md); files in"
                f" {file_dir or '(fileDir of each configure)'}."
                " Stop with Ctrl-C or SIGTERM.",
                flush=True,
            )

        run_loop(
            serve(
                process,
                ready,
                freeze=True,
                pva_port=args.pva_port,
                web_port=args.web_port,
            )
        )
        print("malcolm beamline: stopped", flush=True)
        return 0
    except RuntimeError as e:  # a simulator that did not start
        print(f"malcolm beamline: {e}", file=sys.stderr)
        return 1
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        zebra.stop()
        ioc.stop()


def _raise_interrupt(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt


def add_parser(commands: Any) -> None:
    """Add ``beamline`` to malcolm's subcommands."""
    from malcolm.io.web.cli import add_web_port

    parser = commands.add_parser("beamline", help=HELP, description=HELP)
    parser.add_argument(
        "--prefix", default="BL", help="IOC PV prefix and mri prefix (default BL)"
    )
    parser.add_argument(
        "--file-dir",
        default="",
        metavar="DIR",
        help="default fileDir of the scan's configure (made if missing)",
    )
    parser.add_argument(
        "--pva-port",
        type=int,
        default=5075,
        metavar="PORT",
        help="serve the blocks over pvAccess on PORT (default 5075; 0: off)",
    )
    parser.add_argument(
        "--ca-port",
        type=int,
        default=None,
        metavar="PORT",
        help="Channel Access server port of the simulated IOC (default 5064)",
    )
    parser.add_argument(
        "--process",
        default=str(BEAMLINE_PROCESS_FILE),
        metavar="FILE",
        help="the process file to serve (default: the beamline's)",
    )
    add_web_port(parser)
    parser.set_defaults(func=cmd_beamline)

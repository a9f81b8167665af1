"""The simulated beamline served by ``malcolm beamline`` in a subprocess
(the IOC and the Zebra2 box its own subprocesses), and p4p clients of it.

Run under ``../shared/tools/isolated`` (loopback only).
"""

from __future__ import annotations

import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

from malcolm.sim.beamline_ioc import SimIOC, ca_environment

from ..conftest import ROOT, client_conf, free_port, server_env

PREFIX = "BLT"
SCAN = f"{PREFIX}:SCAN"
READY = "Scan with"


@dataclass
class Beamline:
    """``malcolm beamline`` running: its process, ports, files and output."""

    proc: subprocess.Popen[str]
    conf: dict[str, str]
    file_dir: Path
    ca_port: int
    output: list[str] = field(default_factory=list)
    contexts: list[Any] = field(default_factory=list)
    ioc: SimIOC | None = None  # one a test started in place of the first

    def context(self) -> Any:
        from p4p.client.thread import Context

        ctx = Context("pva", conf=self.conf, useenv=False, nt=False)
        self.contexts.append(ctx)
        return ctx

    def child_pids(self) -> dict[str, int]:
        """The IOC's and the box's pids, as ``malcolm beamline`` printed them."""
        text = "".join(self.output)
        return {
            name: int(pid)
            for name, pid in re.findall(r"simulated (IOC|Zebra2)\b.*?pid (\d+)", text)
        }

    def restart_ioc(self) -> SimIOC:
        """A new simulated IOC of the same prefix and port (the first killed)."""
        self.ioc = SimIOC(PREFIX, env=ca_environment(self.ca_port))
        self.ioc.start()
        return self.ioc

    def stop(self) -> str:
        for ctx in self.contexts:
            ctx.close()
        self.contexts.clear()
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
        try:
            self.proc.wait(60)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        if self.ioc is not None:
            self.ioc.stop()
        return "".join(self.output)


def alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # a zombie (not yet reaped by its parent) is as good as gone
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split(")")[-1].split()[0] != "Z"
    except OSError:
        return False


def launch(file_dir: Path) -> Beamline:
    port = free_port()
    udp_port = free_port(socket.SOCK_DGRAM)
    ca_port = free_port()
    proc = subprocess.Popen(
        [sys.executable, "-m", "malcolm", "beamline", "--prefix", PREFIX,
         "--pva-port", str(port), "--web-port", "0", "--ca-port", str(ca_port),
         "--file-dir", str(file_dir)],
        cwd=ROOT,
        env=server_env(port, udp_port),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )  # fmt: skip
    beamline = Beamline(proc, client_conf(udp_port, port), file_dir, ca_port)
    ready = threading.Event()

    def read() -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            beamline.output.append(line)
            if line.startswith(READY):
                ready.set()

    threading.Thread(target=read, daemon=True).start()
    deadline = time.monotonic() + 90
    while not ready.wait(0.1):
        if proc.poll() is not None or time.monotonic() > deadline:
            out = beamline.stop()
            raise RuntimeError(f"malcolm beamline did not start:\n{out}")
    return beamline


@pytest.fixture(scope="module")
def beamline(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Beamline]:
    served = launch(tmp_path_factory.mktemp("beamline"))
    try:
        yield served
    finally:
        served.stop()


@pytest.fixture(scope="module")
def ctx(beamline: Beamline) -> Any:
    return beamline.context()

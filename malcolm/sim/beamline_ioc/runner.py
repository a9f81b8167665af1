"""Start the simulated beamline IOC as a subprocess, and stop or restart it."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import time
from collections.abc import Mapping

__all__ = ["READY", "SimIOC", "ca_environment"]

#: what the IOC prints on stdout once it serves its PVs
READY = "sim-ioc ready"


def ca_environment(port: int | None = None) -> dict[str, str]:
    """Channel Access variables for talking to IOCs on this host only."""
    env = {
        "EPICS_CA_AUTO_ADDR_LIST": "NO",
        "EPICS_CA_ADDR_LIST": "127.0.0.1",
        "EPICS_CAS_INTF_ADDR_LIST": "127.0.0.1",
        "EPICS_CAS_BEACON_ADDR_LIST": "127.0.0.1",
        "EPICS_CAS_AUTO_BEACON_ADDR_LIST": "NO",
    }
    if port is not None:
        env["EPICS_CA_SERVER_PORT"] = str(port)
        env["EPICS_CA_ADDR_LIST"] = f"127.0.0.1:{port}"
    return env


class SimIOC:
    """The IOC of ``prefix`` in a subprocess (``python -m
    malcolm.sim.beamline_ioc``): ``start`` returns once it prints that it
    serves; ``kill`` ends it at once (as a crash would); ``stop`` closes its
    stdin and waits."""

    def __init__(
        self,
        prefix: str,
        env: Mapping[str, str] | None = None,
        bench_blocks: int = 0,
    ) -> None:
        self.prefix = prefix
        self.bench_blocks = bench_blocks
        self.env = {**os.environ, **ca_environment(), **(env or {})}
        self.process: subprocess.Popen[str] | None = None
        self.output: list[str] = []

    def start(self, timeout: float = 30.0) -> None:
        """Start the IOC; raises RuntimeError if it is not serving in time."""
        command = [sys.executable, "-m", "malcolm.sim.beamline_ioc"]
        self.process = subprocess.Popen(
            [*command, "--prefix", self.prefix]
            + (["--bench-blocks", str(self.bench_blocks)] if self.bench_blocks else []),
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            env=self.env,
        )
        ready = threading.Event()
        threading.Thread(target=self._read, args=(ready,), daemon=True).start()
        deadline = time.monotonic() + timeout
        while not ready.wait(0.05):
            if self.process.poll() is not None or time.monotonic() > deadline:
                self.kill()
                raise RuntimeError(
                    f"sim IOC {self.prefix} did not start:\n" + "".join(self.output)
                )

    def _read(self, ready: threading.Event) -> None:
        assert self.process is not None and self.process.stdout is not None
        for line in self.process.stdout:
            self.output.append(line)
            if line.startswith(READY):
                ready.set()

    @property
    def alive(self) -> bool:
        return self.process is not None and self.process.poll() is None

    def kill(self) -> None:
        """End the IOC at once (SIGKILL), as a crash or power cut would."""
        if self.process is not None and self.process.poll() is None:
            self.process.kill()
        self._reap()

    def stop(self) -> None:
        """Ask the IOC to exit (close its stdin); kill it if it does not."""
        if self.process is None:
            return
        if self.process.stdin is not None:
            try:
                self.process.stdin.close()
            except OSError:
                pass
        try:
            self.process.wait(10)
        except subprocess.TimeoutExpired:
            self.process.kill()
        self._reap()

    def _reap(self) -> None:
        if self.process is None:
            return
        self.process.wait()
        for stream in (self.process.stdin, self.process.stdout):
            if stream is not None:
                try:
                    stream.close()
                except OSError:
                    pass

    def restart(self, timeout: float = 30.0) -> None:
        self.kill()
        self.start(timeout)

"""Shared fixtures of the system tests: a demo process served over pvAccess
in a subprocess (``malcolm demo --pva-port PORT``), and p4p clients of it.

Run under ``../shared/tools/isolated`` (loopback only). Each served process
gets a free TCP port and a free UDP search port; :attr:`Served.conf` is the
client configuration that finds it (``EPICS_PVA_*`` keys).
"""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[2]
READY_TIMEOUT = 30.0


def free_port(kind: int = socket.SOCK_STREAM) -> int:
    """A port nothing on 127.0.0.1 uses now (TCP, or UDP with SOCK_DGRAM)."""
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def client_conf(udp_port: int, tcp_port: int | None = None) -> dict[str, str]:
    """p4p/pvAccess client settings that search only 127.0.0.1:``udp_port``
    by UDP and, given ``tcp_port``, the server there by TCP too
    (``EPICS_PVA_NAME_SERVERS``).

    Fifty clients searching at once by UDP alone lose replies here and back
    off for up to 16 s (a bare p4p server too), so the load test needs the
    TCP search. The client's own UDP port (for beacons) is another one: a
    unicast search to a port clients have bound too may reach a client.
    """
    conf = {
        "EPICS_PVA_ADDR_LIST": f"127.0.0.1:{udp_port}",
        "EPICS_PVA_AUTO_ADDR_LIST": "NO",
        "EPICS_PVA_BROADCAST_PORT": str(free_port(socket.SOCK_DGRAM)),
    }
    if tcp_port:
        conf["EPICS_PVA_NAME_SERVERS"] = f"127.0.0.1:{tcp_port}"
    return conf


@dataclass
class Served:
    """A served process: its subprocess, ports and output so far."""

    proc: subprocess.Popen[str]
    port: int
    udp_port: int
    conf: dict[str, str]
    started: float
    contexts: list[Any] = field(default_factory=list)

    def context(self, **kws: Any) -> Any:
        """A p4p client Context of this server (closed with the fixture);
        values are not unwrapped (``nt=False``) unless asked."""
        from p4p.client.thread import Context

        kws.setdefault("nt", False)
        ctx = Context("pva", conf=self.conf, useenv=False, **kws)
        self.contexts.append(ctx)
        return ctx

    def stop(self) -> str:
        """SIGINT the process, wait for it, and return what it printed."""
        for ctx in self.contexts:
            ctx.close()
        self.contexts.clear()
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
        try:
            out, _ = self.proc.communicate(timeout=20)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            out, _ = self.proc.communicate()
        return out


def server_conf(udp_port: int) -> dict[str, str]:
    """pvAccess server settings: 127.0.0.1 only, searched on ``udp_port``."""
    return {
        "EPICS_PVAS_INTF_ADDR_LIST": "127.0.0.1",
        "EPICS_PVAS_BROADCAST_PORT": str(udp_port),
        "EPICS_PVAS_BEACON_ADDR_LIST": f"127.0.0.1:{udp_port}",
        "EPICS_PVAS_AUTO_BEACON_ADDR_LIST": "NO",
    }


def server_env(port: int, udp_port: int) -> dict[str, str]:
    env = dict(os.environ)
    env.update(server_conf(udp_port), PYTHONUNBUFFERED="1")
    return env


@contextlib.contextmanager
def served_in_process(process: Any) -> Iterator[tuple[Any, Any, Any]]:
    """``process`` started in a thread and served over pvAccess in this
    process (free ports), with a p4p client of it: ``(tp, server, ctx)``;
    all three closed on the way out."""
    from p4p.client.thread import Context

    from malcolm.embed import start_process
    from malcolm.io.pva import start_pva_server

    tp = start_process(process)
    udp = free_port(socket.SOCK_DGRAM)
    conf = server_conf(udp)
    server = process.call_threadsafe(start_pva_server, process, 0, conf).result(10)
    ctx = Context("pva", conf=client_conf(udp), useenv=False, nt=False)
    try:
        yield tp, server, ctx
    finally:
        ctx.close()
        process.call_threadsafe(server.close).result(10)
        tp.stop()


def launch(*args: str, port: int | None = None, udp_port: int | None = None) -> Served:
    """Start ``python -m malcolm ARGS --pva-port PORT`` (not waiting)."""
    port = port or free_port()
    udp_port = udp_port or free_port(socket.SOCK_DGRAM)
    proc = subprocess.Popen(
        [sys.executable, "-m", "malcolm", *args, "--pva-port", str(port)],
        cwd=ROOT,
        env=server_env(port, udp_port),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    return Served(proc, port, udp_port, client_conf(udp_port, port), time.monotonic())


def wait_ready(served: Served, mri: str = "HELLO") -> float:
    """Wait until a get of ``mri`` succeeds; seconds since launch."""
    from p4p.client.thread import Context, TimeoutError

    ctx = Context("pva", conf=served.conf, useenv=False, nt=False)
    try:
        deadline = time.monotonic() + READY_TIMEOUT
        while True:
            if served.proc.poll() is not None:
                raise RuntimeError(f"server exited: {served.stop()}")
            try:
                ctx.get(mri, timeout=0.5)
                return time.monotonic() - served.started
            except TimeoutError:
                if time.monotonic() > deadline:
                    raise
    finally:
        ctx.close()


def serve_demo() -> Served:
    """The demo process served over pvAccess, ready (a get succeeded)."""
    served = launch("demo")
    try:
        wait_ready(served)
    except BaseException:
        served.stop()
        raise
    return served


@pytest.fixture(scope="module")
def demo() -> Iterator[Served]:
    """One served demo per test module."""
    served = serve_demo()
    yield served
    served.stop()


@pytest.fixture(scope="module")
def ctx(demo: Served) -> Any:
    """A p4p client Context of the module's served demo (values not unwrapped)."""
    return demo.context()

"""``malcolm sim-zebra2`` in a subprocess: prints the address it serves,
answers on it, exits 0 on SIGTERM or Ctrl-C, and exits 1 with a message (no
traceback) when it cannot bind its port."""

from __future__ import annotations

import re
import signal
import socket
import subprocess
import sys

import pytest


def start(*args: str) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "malcolm", "sim-zebra2", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def ask(port: int, line: str, host: str = "127.0.0.1") -> str:
    with socket.create_connection((host, port), timeout=10) as sock:
        sock.sendall(line.encode() + b"\n")
        return sock.makefile().readline().strip()


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_serves_the_printed_address_and_exits_cleanly(sig: signal.Signals) -> None:
    proc = start("--control-port", "0", "--data-port", "0", "--layout", "tier1")
    try:
        line = proc.stdout.readline()  # type: ignore[union-attr]
        m = re.match(r"zebra2 sim \(tier1\): control 127\.0\.0\.1:(\d+) data "
                     r"127\.0\.0\.1:(\d+)$", line.strip())  # fmt: skip
        assert m, line
        assert ask(int(m.group(1)), "*IDN?").startswith("OK =PandA SW: 4.1-dirty")
        with socket.create_connection(("127.0.0.1", int(m.group(2))), timeout=10) as d:
            d.sendall(b"BARE\n")  # a data client stays connected
            proc.send_signal(sig)
            assert proc.wait(timeout=20) == 0
    finally:
        proc.kill()
        proc.wait()
    assert proc.stderr.read() == ""  # type: ignore[union-attr]


def test_a_taken_port_is_a_message_not_a_traceback() -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        proc = start("--control-port", str(port), "--data-port", "0")
        _, err = proc.communicate(timeout=30)
    assert proc.returncode == 1
    assert err.startswith("malcolm sim-zebra2: ") and "Traceback" not in err


def test_restarts_on_the_same_ports_after_being_killed() -> None:
    """What a client's reconnection test does: kill the box mid-connection,
    start it again on the same address, and it answers there."""
    host = "127.0.0.15"
    args = ("--host", host, "--control-port", "8888", "--data-port", "8889")
    first = start(*args)
    try:
        assert first.stdout.readline().startswith("zebra2 sim")  # type: ignore[union-attr]
        client = socket.create_connection((host, 8888), timeout=10)
        client.sendall(b"PCOMP1.START=5\n")
        assert client.makefile().readline() == "OK\n"
        first.kill()
        first.wait(timeout=20)
        assert client.recv(100) == b""  # the box went away
        client.close()
    finally:
        first.kill()
        first.wait()
    second = start(*args)
    try:
        assert second.stdout.readline().startswith("zebra2 sim")  # type: ignore[union-attr]
        # a fresh box: the value written before the kill is gone
        assert ask(8888, "PCOMP1.START?", host) == "OK =0"
        second.send_signal(signal.SIGTERM)
        assert second.wait(timeout=20) == 0
    finally:
        second.kill()
        second.wait()

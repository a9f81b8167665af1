"""``malcolm get|put|call|ls`` against a demo process served over pvAccess
in a subprocess (run under ../shared/tools/isolated: loopback only).

The served process (:func:`serve_demo`) is shared with
test_client_two_process.py: the demo's blocks, the ``localhost`` block list,
and the pvAccess server on a free port.
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

# the served side is the pvAccess server's (branch pva-server)
pytest.importorskip("malcolm.io.pva.server")

ROOT = Path(__file__).resolve().parents[2]

SERVE_A = """
import asyncio, sys
from malcolm.demo import demo_process
from malcolm.io.pva.client_blocklist import add_block_list
from malcolm.io.pva.server import start_pva_server

async def main():
    process = demo_process()
    add_block_list(process)
    await process.start()
    await start_pva_server(process, int(sys.argv[1]))
    print("ready", flush=True)
    await asyncio.Event().wait()

asyncio.run(main())
"""


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def serve_demo(port: int) -> subprocess.Popen[str]:
    """The demo process served on ``port``, once it has said it is ready."""
    proc = subprocess.Popen(
        [sys.executable, "-c", SERVE_A, str(port)],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        cwd=ROOT,
        env={**os.environ, "EPICS_PVAS_BROADCAST_PORT": str(free_port())},
    )
    assert proc.stdout is not None
    line = proc.stdout.readline()
    if line.strip() != "ready":
        proc.kill()
        raise AssertionError(
            f"the served demo did not start: {line}{proc.stdout.read()}"
        )
    return proc


def stop(proc: subprocess.Popen[str]) -> None:
    proc.kill()
    proc.communicate(timeout=20)


@pytest.fixture(scope="module")
def address() -> Iterator[str]:
    port = free_port()
    proc = serve_demo(port)
    try:
        yield f"127.0.0.1:{port}"
    finally:
        stop(proc)


def malcolm(address: str, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "malcolm", *args, "--address", address],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=60,
    )


def ok(result: subprocess.CompletedProcess[str]) -> str:
    assert result.returncode == 0, result.stderr
    assert result.stderr == ""
    return result.stdout


def refused(result: subprocess.CompletedProcess[str]) -> str:
    """The one line of a refused command (exit 1, nothing on stdout)."""
    assert result.returncode == 1, result
    assert result.stdout == ""
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    return lines[0]


def test_get_a_whole_block_and_one_field(address):
    out = ok(malcolm(address, "get", "HELLO"))
    assert out.splitlines() == [
        "HELLO: Says hello",
        "  health = OK",
        "  state = Ready",
        "  reset()  (not now)",
        "  disable()",
        "  greet(name, sleep)",
        "  error()",
    ]
    assert (
        ok(malcolm(address, "get", "MOTOR:X.velocity")) == "MOTOR:X.velocity = 100.0\n"
    )
    data = json.loads(ok(malcolm(address, "get", "COUNTER", "--json")))
    assert data["typeid"] == "malcolm:core/Block:1.0"
    assert data["meta"]["fields"][:2] == ["health", "state"]
    assert data["counter"]["typeid"] == "epics:nt/NTScalar:1.0"
    field = json.loads(ok(malcolm(address, "get", "COUNTER.counter", "--json")))
    assert field["meta"]["typeid"] == "malcolm:core/NumberMeta:1.0"


def test_put_then_get(address):
    assert ok(malcolm(address, "put", "COUNTER.counter", "41")) == (
        "COUNTER.counter = 41.0\n"
    )
    assert ok(malcolm(address, "call", "COUNTER.increment")) == ""
    assert ok(malcolm(address, "get", "COUNTER.counter")) == "COUNTER.counter = 42.0\n"


def test_call_with_arguments(address):
    out = ok(malcolm(address, "call", "HELLO.greet", "name=pvAccess", "sleep=0"))
    assert out == "greeting = Hello pvAccess\n"
    out = ok(malcolm(address, "call", "HELLO.greet", "name=42", "--json"))
    assert json.loads(out) == {"greeting": "Hello 42"}  # text stays text


def test_ls_lists_the_served_blocks(address):
    assert ok(malcolm(address, "ls")).split() == [
        "HELLO",
        "COUNTER",
        "MOTOR:X",
        "MOTOR:Y",
        "DET1",
        "DET2",
        "SCAN",
    ]


def test_errors_are_one_line_and_exit_1(address):
    where = f"pva://{address}"
    assert refused(malcolm(address, "put", "COUNTER.counter", "abc")) == (
        f"malcolm put: {where}/COUNTER.counter: expected a number (float64), got 'abc'"
    )
    assert refused(malcolm(address, "get", "COUNTER.nope")) == (
        f"malcolm get: {where}/COUNTER has no field 'nope' (fields: health, state,"
        " reset, disable, counter, delta, zero, increment)"
    )
    assert refused(malcolm(address, "put", "COUNTER.state", "Ready")) == (
        f"malcolm put: {where}/COUNTER.state is read-only"
    )
    assert refused(malcolm(address, "call", "HELLO.error")) == (
        f"malcolm call: {where}/HELLO.error: RuntimeError: You called method error()"
    )
    line = refused(malcolm(address, "call", "SCAN.run"))
    assert line.startswith(f"malcolm call: {where}/SCAN.run: NotAllowedError: SCAN:")
    assert refused(malcolm(address, "call", "HELLO.greet", "nam=x")) == (
        f"malcolm call: {where}/HELLO.greet takes no argument 'nam'"
        " (it takes: name, sleep)"
    )
    assert refused(malcolm(address, "get", "NOBLOCK", "--timeout", "1")) == (
        f"malcolm get: {where}/NOBLOCK: no answer within 1.0 s (is a server"
        " there, and does it have that block?)"
    )


def test_a_bad_address_is_one_line():
    result = malcolm("127.0.0.1:notaport", "ls")
    assert refused(result) == (
        "malcolm ls: pvAccess address '127.0.0.1:notaport': port 'notaport' is"
        " not a number"
    )


def test_no_server_is_one_line():
    port = free_port()
    line = refused(malcolm(f"127.0.0.1:{port}", "get", "HELLO", "--timeout", "0.5"))
    assert line.startswith(f"malcolm get: pva://127.0.0.1:{port}/HELLO: no answer")

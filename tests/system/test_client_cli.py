"""``malcolm get|put|call|ls`` against the demo served over pvAccess
(``malcolm demo --pva-port PORT`` in a subprocess, tests/system/conftest.py;
run under ../shared/tools/isolated: loopback only).

:func:`serve_demo` and :func:`stop` are shared with the other
test_client*.py modules.
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator

import pytest

from .conftest import ROOT, Served, free_port, launch, wait_ready


def serve_demo(port: int) -> Served:
    """``malcolm demo`` serving pvAccess on ``port``, once a get succeeds."""
    served = launch("demo", port=port)
    try:
        wait_ready(served)
    except BaseException:
        served.stop()
        raise
    return served


def stop(served: Served) -> None:
    """Kill the served process (no clean stop: as if it died)."""
    for context in served.contexts:
        context.close()
    served.contexts.clear()
    if served.proc.returncode is None:
        served.proc.kill()
        served.proc.communicate(timeout=20)


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

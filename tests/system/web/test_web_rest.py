"""The REST face and ``--web-port`` of ``malcolm demo``."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
from pathlib import Path

import aiohttp
import pytest

from malcolm.cli import build_parser

from .conftest import run


def test_rest_get_put_post_and_errors_as_status_codes(served):
    async def body():
        async with aiohttp.ClientSession() as s:
            base = served.url + "rest/"

            async def call(method, path, **kw):
                async with s.request(method, base + path, **kw) as r:
                    return r.status, await r.json()

            status, blocks = await call("GET", "")
            assert status == 200 and "SCAN" in blocks
            assert (await call("GET", "MOTOR:X"))[1] == served.get(["MOTOR:X"])
            assert await call("GET", "COUNTER/counter/value") == (200, 0)
            assert await call("PUT", "COUNTER/counter", data="12") == (200, 12)
            assert served.get(["COUNTER", "counter", "value"]) == 12
            assert await call("POST", "HELLO/greet", json={"name": "curl"}) == (
                200,
                {"greeting": "Hello curl"},
            )
            assert await call("POST", "COUNTER/increment") == (200, None)
            for method, path, kw, code, text in [
                ("GET", "NOPE", {}, 404, "NotFoundError: no block 'NOPE'"),
                ("GET", "COUNTER/nope", {}, 404, "NotFoundError"),
                ("PUT", "COUNTER/counter", {"data": "{bad"}, 400, "malformed JSON"),
                ("PUT", "COUNTER/counter", {"data": '"x"'}, 400, "BadValueError"),
                ("PUT", "COUNTER", {"data": "1"}, 404, "PUT needs"),
                ("POST", "HELLO/greet", {"data": "[1]"}, 400, "a JSON object"),
                ("POST", "HELLO/greet", {"json": {"x": 1}}, 400, "HELLO.greet.x"),
                ("POST", "SCAN/run", {}, 409, "NotAllowedError"),
                ("POST", "HELLO/nope", {}, 404, "NotFoundError"),
                ("PUT", "COUNTER/counter", {"data": "1" * (2 << 20)}, 413, ""),
            ]:
                async with s.request(method, base + path, **kw) as r:
                    assert r.status == code, (method, path, await r.text())
                    assert text in await r.text()
            assert served.get(["COUNTER", "counter", "value"]) == 13

    run(body())


def test_web_port_option():
    parser = build_parser()
    assert parser.parse_args(["demo"]).web_port == 8008
    assert parser.parse_args(["demo", "--web-port", "0"]).web_port == 0
    assert parser.parse_args(["serve", "x.yaml", "--web-port", "9"]).web_port == 9
    with pytest.raises(SystemExit):
        parser.parse_args(["demo", "--web-port", "70000"])


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _start(*argv: str) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "malcolm", *argv],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )


def _stop(proc: subprocess.Popen) -> str:
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, err
    assert "Traceback" not in err
    return err


def _rest_and_gui(port: int) -> None:
    async def body():
        async with aiohttp.ClientSession() as s:
            async with s.get(f"http://127.0.0.1:{port}/rest/HELLO/state/value") as r:
                assert await r.json() == "Ready"
            async with s.get(f"http://127.0.0.1:{port}/") as r:
                assert r.status == 200 and "<html" in (await r.text()).lower()

    run(body())


def test_malcolm_demo_serves_the_web_and_prints_its_address():
    port = _free_port()
    proc = _start("demo", "--web-port", str(port), "--pva-port", "0")
    try:
        line = proc.stdout.readline()
        assert line.startswith(f"malcolm demo: web GUI at http://localhost:{port}/")
        _rest_and_gui(port)
    finally:
        _stop(proc)


def test_malcolm_serve_serves_the_web_too(tmp_path):
    port = _free_port()
    process_file = (
        Path(__file__).resolve().parents[3] / "malcolm/blocks/demo/process.yaml"
    )
    proc = _start(
        "serve", str(process_file), "--web-port", str(port), "--pva-port", "0"
    )
    try:
        line = proc.stdout.readline()
        assert line.startswith(f"malcolm serve: web GUI at http://localhost:{port}/")
        _rest_and_gui(port)
    finally:
        _stop(proc)


def test_a_port_in_use_is_reported_and_serving_goes_on():
    with socket.socket() as taken:
        taken.bind(("0.0.0.0", 0))
        taken.listen()
        port = taken.getsockname()[1]
        proc = _start("demo", "--web-port", str(port), "--pva-port", "0")
        try:
            for line in proc.stdout:
                if line.startswith("Serving until interrupted"):
                    break
        finally:
            err = _stop(proc)
    assert f"malcolm demo: no web server on port {port}: " in err


def _loaded(pid: int, name: str) -> bool:
    """Whether process ``pid`` has mapped a shared library under ``name``/."""
    maps = Path(f"/proc/{pid}/maps").read_text()
    return f"/{name}/" in maps


def test_the_web_stack_loads_when_the_first_client_connects():
    port = _free_port()
    proc = _start("demo", "--web-port", str(port), "--pva-port", "0")
    try:
        line = proc.stdout.readline()
        assert line.startswith(f"malcolm demo: web GUI at http://localhost:{port}/")
        for line in proc.stdout:
            if line.startswith("Serving until interrupted"):
                break
        assert not _loaded(proc.pid, "aiohttp")  # listening, nothing imported
        _rest_and_gui(port)  # the first connection waits while it loads
        assert _loaded(proc.pid, "aiohttp")
    finally:
        _stop(proc)

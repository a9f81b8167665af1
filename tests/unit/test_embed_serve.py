"""`malcolm serve` and the serve()/watch_states() helpers behind it."""

from __future__ import annotations

import asyncio
import logging
import os
import signal
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from malcolm.embed import serve, watch_states


def demo_process():
    from malcolm.demo import demo_process  # lazily: see test_embed.py

    return demo_process()


def test_watch_states_logs_every_change(caplog):
    async def main():
        process = demo_process()
        subs = watch_states(process)
        await process.start()
        await process.post(["HELLO", "disable"])
        await process.stop()
        for sub in subs:
            process.unsubscribe(sub)

    with caplog.at_level(logging.INFO, logger="malcolm.serve"):
        asyncio.run(main())
    lines = [r.getMessage() for r in caplog.records]
    assert "HELLO: Disabled -> Resetting" in lines
    assert "HELLO: Resetting -> Ready" in lines
    assert "HELLO: Ready -> Disabling" in lines
    assert "SCAN: Resetting -> Ready" in lines


def test_watch_states_logs_health_when_a_block_faults(caplog):
    async def main():
        process = demo_process()
        watch_states(process)
        await process.start()
        controller = process.get_controller("COUNTER")
        await controller.go_fault("it broke")
        await process.stop()

    with caplog.at_level(logging.INFO, logger="malcolm.serve"):
        asyncio.run(main())
    warnings = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert "COUNTER: health: it broke" in warnings
    assert "COUNTER: Ready -> Fault" in [r.getMessage() for r in caplog.records]


def test_serve_runs_until_signalled_then_stops(caplog):
    seen = []

    def ready(process):
        seen.append(process.get(["COUNTER", "state", "value"]))
        loop = asyncio.get_running_loop()
        loop.call_later(0.05, os.kill, os.getpid(), signal.SIGUSR1)

    async def main():
        process = demo_process()
        await serve(process, ready, signals=[signal.SIGUSR1])
        return process

    with caplog.at_level(logging.INFO, logger="malcolm.serve"):
        process = asyncio.run(main())
    assert seen == ["Ready"]
    assert not process.started
    assert "stopping" in [r.getMessage() for r in caplog.records]


# ---- the command, in a subprocess


def start_serve(*args: str, cwd: Path) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "malcolm", "serve", *args],
        cwd=cwd,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def read_until(stream, marker: str, timeout: float) -> list[str]:
    lines: list[str] = []
    done = threading.Event()

    def read():
        for line in stream:
            lines.append(line.rstrip("\n"))
            if marker in line:
                break
        done.set()

    threading.Thread(target=read, daemon=True).start()
    done.wait(timeout)
    return lines


def test_serve_reports_problems_and_starts_nothing(tmp_path):
    proc = tmp_path / "proc.yaml"
    proc.write_text("block.nowhere.Thing:\n    mri: A:B\n    x: 1\n")
    p = start_serve(str(proc), cwd=tmp_path)
    out, err = p.communicate(timeout=60)
    assert p.returncode == 1
    assert f"{proc}:1: no definition 'nowhere.Thing'" in err
    assert "nothing started" in err
    assert "Traceback" not in err and out == ""


def test_serve_of_a_missing_file(tmp_path):
    p = start_serve(str(tmp_path / "missing.yaml"), cwd=tmp_path)
    out, err = p.communicate(timeout=60)
    assert p.returncode == 1
    assert "missing.yaml" in err and "Traceback" not in err


@pytest.fixture
def process_file(tmp_path):
    pytest.importorskip(
        "malcolm.config.build",
        reason="build_process (malcolm.config.build) has not landed yet",
    )
    blocks = tmp_path / "blocks" / "t"
    blocks.mkdir(parents=True)
    (blocks / "Hello.yaml").write_text("parts.HelloPart:\n    name: hello\n")
    (blocks / "Counter.yaml").write_text("parts.CounterPart:\n    name: counter\n")
    proc = tmp_path / "proc.yaml"
    proc.write_text(
        "define.String:\n    name: bl\n    value: T\n"
        "block.t.Hello:\n    mri: '{bl}:HELLO'\n"
        "block.t.Counter:\n    mri: '{bl}:COUNTER'\n"
    )
    return proc


@pytest.mark.parametrize(
    ("sig", "options"),
    [(signal.SIGINT, ["-I", "blocks"]), (signal.SIGTERM, [])],  # blocks/ found
)
def test_serve_logs_state_changes_and_stops_cleanly(
    process_file, tmp_path, sig, options
):
    p = start_serve(str(process_file), *options, cwd=tmp_path)
    try:
        lines = read_until(p.stdout, "Ctrl-C", timeout=60)
        assert any("Ctrl-C" in line for line in lines), (lines, p.poll())
        assert any("T:HELLO" in line for line in lines)
        assert any("T:COUNTER" in line for line in lines)
        p.send_signal(sig)
        _, err = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    assert p.returncode == 0, err
    assert "T:HELLO: Disabled -> Resetting" in err
    assert "T:HELLO: Resetting -> Ready" in err
    assert "T:COUNTER: Resetting -> Ready" in err
    assert "Traceback" not in err
    assert "Finished processing state" not in err  # transitions' chatter

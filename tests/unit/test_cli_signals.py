"""Signals and closed pipes on the command line, with real subprocesses: a
scan interrupted by Ctrl-C or SIGTERM is aborted, the exit status says so,
and no traceback is ever printed (issue 7 item 10)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from malcolm.cli import main

SCRIPT = Path(sys.executable).with_name("malcolm")
#: the command line, saying "R" on stdout once malcolm.cli.main is running
#: (a Ctrl-C before that hits Python's own start-up, which malcolm cannot
#: reach; `malcolm.entry` makes the window before main a single import)
READY_FIRST = (
    "import os, sys\n"
    "import malcolm.cli as cli\n"
    "parser = cli.build_parser\n"
    "cli.build_parser = lambda: (os.write(1, b'R'), parser())[1]\n"
    "sys.exit(cli.main())\n"
)


def start(*argv: str, ready_first: bool = False) -> subprocess.Popen[bytes]:
    command = (
        [sys.executable, "-c", READY_FIRST, *argv]
        if ready_first
        else [str(SCRIPT), *argv]
    )
    return subprocess.Popen(
        command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=Path.home()
    )


def read_until(process: subprocess.Popen[bytes], text: bytes) -> bytes:
    """What ``process`` writes to stdout up to and including ``text``."""
    assert process.stdout is not None
    seen = b""
    while text not in seen:
        chunk = os.read(process.stdout.fileno(), 4096)
        assert chunk, f"stdout closed before {text!r}: {seen!r}"
        seen += chunk
    return seen


def finish(process: subprocess.Popen[bytes], before: bytes) -> tuple[str, str]:
    out, err = process.communicate(timeout=60)
    return (before + out).decode(), err.decode()


@pytest.mark.parametrize(
    ("sig", "status"), [(signal.SIGINT, 130), (signal.SIGTERM, 143)]
)
def test_a_signal_during_demo_scan_aborts_it_and_exits_non_zero(sig, status):
    process = start("demo", "--scan", "--duration", "5")
    before = read_until(process, b"SCAN [")  # configured: the run has begun
    process.send_signal(sig)
    out, err = finish(process, before)
    name = signal.Signals(sig).name
    assert process.returncode == status
    assert out.endswith("\nSCAN Aborted\n")
    assert err == (
        f"malcolm demo: {name}: SCAN Aborted\nmalcolm demo: {name}: stopped\n"
    )


def test_sigterm_stops_the_served_demo_cleanly():
    process = start("demo")
    before = read_until(process, b"Serving until interrupted")
    process.send_signal(signal.SIGTERM)
    out, err = finish(process, before)
    assert process.returncode == 0
    assert err == "malcolm demo: SIGTERM: stopped\n"


@pytest.mark.parametrize("argv", [("demo", "--scan", "--duration", "5"), ("demo",)])
def test_ctrl_c_during_start_up_is_one_line_never_a_traceback(argv):
    process = start(*argv, ready_first=True)
    before = read_until(process, b"R")
    process.send_signal(signal.SIGINT)
    out, err = finish(process, before)
    assert "Traceback" not in err
    if argv[-1] != "demo":  # a scan cut short fails
        assert process.returncode == 130
    assert err in (
        "malcolm: interrupted\n",
        "malcolm demo: interrupted\n",
        "malcolm demo: SIGINT: stopped\n",
        "malcolm demo: SIGINT: SCAN Aborted\nmalcolm demo: SIGINT: stopped\n",
    )


def test_output_to_a_closed_pipe_ends_quietly():
    read, write = os.pipe()
    os.close(read)  # as `head` does once it has its lines
    try:
        result = subprocess.run(
            [str(SCRIPT), "graph", "runnable_device"],
            stdout=write,
            stderr=subprocess.PIPE,
            timeout=60,
        )
    finally:
        os.close(write)
    assert result.stderr == b""
    assert result.returncode == 141


@pytest.mark.parametrize("argv", [["demo", "--scan"], ["serve", "process.yaml"]])
def test_ctrl_c_while_building_is_reported_in_one_line(argv, monkeypatch, capsys):
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr("malcolm.demo.demo_process", interrupted)
    monkeypatch.setattr("malcolm.embed.from_file", interrupted)
    assert main(argv) == 130
    assert capsys.readouterr().err == f"malcolm {argv[0]}: interrupted\n"

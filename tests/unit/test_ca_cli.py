"""The command lines issue 10 adds: ``sim-ioc`` and ``serve --ca-backend``."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def malcolm(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "malcolm", *args],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=ROOT,
    )


def test_serve_refuses_an_unknown_ca_backend_naming_the_known_ones():
    done = malcolm(
        "serve", "--ca-backend", "nosuch", "malcolm/blocks/zebra2/process.yaml"
    )
    assert done.returncode == 1
    assert "--ca-backend" in done.stderr and "there are: soft, pyepics" in done.stderr
    assert "Traceback" not in done.stderr


def test_sim_ioc_is_a_subcommand():
    done = malcolm("sim-ioc", "--help")
    assert done.returncode == 0 and "--prefix" in done.stdout

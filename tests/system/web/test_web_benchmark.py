"""``benchmarks/web.py`` still runs and prints its table (its figures depend
on the machine and are not asserted; docs/web.md gives a run's)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]


def test_the_web_benchmark_prints_its_table():
    out = subprocess.run(
        [sys.executable, "-m", "benchmarks.web", "--n", "50", "--clients", "5"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert lines[0].split()[:3] == ["case", "measured", "target"]
    text = "\n".join(lines)
    for case in (
        "WebSocket Get round trip: malcolm",
        "put -> subscriber update: malcolm",
        "5 clients, 50-point scan: server CPU",
        "GUI first paint of SCAN (Chromium)",
    ):
        assert case in text, text
    (ending,) = [line for line in lines if "clients ending with the final" in line]
    assert "5 of 5" in ending, ending
    ratios = [line for line in lines if line.strip().startswith("ratio")]
    assert len(ratios) == 2 and all("<= 1.5x" in line for line in ratios)

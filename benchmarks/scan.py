"""Benchmarks of the scan-points engine against issue 8's targets.

    .venv/bin/python -m benchmarks.scan

For each case it times what a configure does with the scan's points, on a
generator dict built with `malcolm.scan.gda` as GDA would send it: validate
it (`PointGeneratorMeta`), build the `ScanPoints`, work out the steps per
run, and compute the first chunk of the first run. Each repetition starts
cold (the scans `scan_points` keeps are forgotten first). It prints the
median time and the peak memory allocated (tracemalloc, in a separate
repetition), beside the target, the figures of issue 8 (the reference,
pymalcolm 6.3, and malcolm before this work), and scanspec doing the same
work on the same path on the same run (calculate the dimensions and consume
the first chunk).

It also times ``import malcolm.scan`` (which no longer imports scanspec),
importing scanspec itself, and `malcolm points` streaming the start of a
1e8-point scan (the peak RSS of that process).
"""

from __future__ import annotations

import argparse
import math
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
import tracemalloc
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from scanspec.core import Path
from scanspec.specs import Linspace, Spec, Spiral

from malcolm.core import PointGeneratorMeta
from malcolm.scan import gda, scan_points
from malcolm.scan.load import forget_built_scans
from malcolm.scan.points import CHUNK_SIZE

MIB = 1024 * 1024
#: address space allowed to ``malcolm points`` on the 1e8-point scan
LIMIT_MIB = 2048


@dataclass
class Case:
    """One configure-equivalent case and what issue 8 says about it."""

    name: str
    generator: dict[str, Any]
    axes_to_move: list[str] | None
    spec: Spec[str] | None
    target_ms: float | None
    target_mib: float | None
    reference: str
    before: str
    repeats: int | None = None


def spiral_radius(points: int, scale: float = 1.0) -> float:
    """The radius of a SpiralGenerator with ``points`` points."""
    return math.sqrt((points - 0.5) / math.pi) * scale


def with_circle(data: dict[str, Any]) -> dict[str, Any]:
    """``data`` with a circular region over its x and y."""
    circle = {
        "typeid": "scanpointgenerator:roi/CircularROI:1.0",
        "centre": [0.5, 0.5],
        "radius": 0.5,
    }
    excluder = {
        "typeid": "scanpointgenerator:excluder/ROIExcluder:1.0",
        "axes": ["x", "y"],
        "rois": [circle],
    }
    return {**data, "excluders": [excluder]}


def cases() -> list[Case]:
    """The three cases of issue 8's acceptance, and a region on the largest
    grid (the one case that evaluates a dimension when built)."""
    grid = gda.compound(gda.line("y", 1000), gda.line("x", 1000))
    radius = spiral_radius(1_000_000)
    spiral = gda.compound(gda.spiral("x", "y", radius))
    snake = gda.compound(
        gda.line("y", 10_000), gda.line("x", 10_000, alternate=True), duration=0.001
    )
    # scanspec's Spiral of about the same number of points and extent
    spec_spiral = Spiral("x", 0, 2 * radius, 1.0, "y", 0)
    return [
        Case(
            "1000x1000 grid",
            grid,
            ["x"],
            Linspace("y", 0, 1, 1000) * Linspace("x", 0, 1, 1000),
            10,
            50,
            "2.8 ms, 37 MiB",
            "173 ms, 130 MiB",
        ),
        Case(
            "1e6-point spiral",
            spiral,
            None,
            spec_spiral,
            150,
            None,
            "189 ms",
            "537 ms, 222 MiB",
        ),
        Case(
            "1e8-point snake grid",
            snake,
            ["x"],
            Linspace("y", 0, 1, 10_000) * ~Linspace("x", 0, 1, 10_000),
            1000,
            None,
            "-",
            "112 s, 15 GB, then Fault",
        ),
        Case(
            "1e8 grid, circle region",
            with_circle(snake),
            None,
            None,
            None,
            None,
            "-",
            "-",
            repeats=1,
        ),
    ]


def configure(case: Case) -> None:
    """What a configure does with the scan's points."""
    value = PointGeneratorMeta("generator").validate(case.generator)
    points = scan_points(value)
    steps = points.steps_per_run(case.axes_to_move)
    chunk = points.chunk(0, min(steps, CHUNK_SIZE))
    assert len(chunk) > 0


def scanspec_same_work(spec: Spec[str]) -> None:
    """scanspec computing the same path: its dimensions and the first chunk."""
    stack = spec.calculate()
    Path(stack).consume(CHUNK_SIZE)


def median_seconds(fn: Callable[[], None], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        forget_built_scans()
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def peak_mib(fn: Callable[[], None]) -> float:
    forget_built_scans()
    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1] / MIB
    finally:
        tracemalloc.stop()


def import_seconds(statement: str, repeats: int) -> float:
    """Median wall time of a fresh interpreter running ``statement``, less
    that of an empty one."""

    def run(code: str) -> float:
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-c", code], check=True)
        return time.perf_counter() - t0

    empty = statistics.median(run("pass") for _ in range(repeats))
    return statistics.median(run(statement) for _ in range(repeats)) - empty


def peak_rss_mib(pid: int) -> float:
    """The peak resident memory of a running process (Linux), in MiB."""
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
    return math.nan


def points_streaming(output_mib: int) -> tuple[float, float]:
    """Run ``malcolm points`` on a 1e8-point file, limited to `LIMIT_MIB` of
    address space, and read the first ``output_mib`` MiB of its output;
    return the MiB/s and its peak RSS."""
    import json

    snake = gda.compound(gda.line("y", 10_000), gda.line("x", 10_000, alternate=True))
    with tempfile.TemporaryDirectory() as tmp:
        file = os.path.join(tmp, "scan.json")
        with open(file, "w") as f:
            json.dump(snake, f)
        t0 = time.perf_counter()
        child = subprocess.Popen(
            [sys.executable, "-m", "malcolm", "points", file],
            stdout=subprocess.PIPE,
            # were it to hold every point, it would fail here, not swap
            preexec_fn=lambda: resource.setrlimit(
                resource.RLIMIT_AS, (LIMIT_MIB * MIB, LIMIT_MIB * MIB)
            ),
        )
        assert child.stdout is not None
        left = output_mib * MIB
        while left > 0:
            data = child.stdout.read(min(left, MIB))
            if not data:
                break
            left -= len(data)
        elapsed = time.perf_counter() - t0
        rss = peak_rss_mib(child.pid) if left == 0 else math.nan
        child.stdout.close()  # the child ends on its broken pipe
        status = child.wait()
        if left > 0:
            raise RuntimeError(f"malcolm points ended early (status {status})")
    return output_mib / elapsed, rss


def main(repeats: int, stream_mib: int) -> None:
    print(
        f"{'configure-equivalent':<24} {'target':>18} {'reference':>16} "
        f"{'malcolm before':>24} {'measured':>10} {'peak mem':>10} "
        f"{'scanspec':>10}"
    )
    for case in cases():
        count = case.repeats or repeats
        configure(case)  # imports and first-time set-up out of the way
        seconds = median_seconds(lambda case=case: configure(case), count)
        mib = peak_mib(lambda case=case: configure(case))
        raw = "-"
        if case.spec is not None:
            spec = case.spec
            raw_s = median_seconds(lambda spec=spec: scanspec_same_work(spec), count)
            raw = f"{raw_s * 1e3:.1f} ms"
        target = "-"
        if case.target_ms is not None:
            target = f"<= {case.target_ms:g} ms" + (
                f", {case.target_mib:g} MiB" if case.target_mib else ""
            )
        print(
            f"{case.name:<24} {target:>18} {case.reference:>16} {case.before:>24} "
            f"{seconds * 1e3:>7.2f} ms {mib:>6.2f} MiB {raw:>10}"
        )
    print(
        "(configure-equivalent: validate + build + steps_per_run + the first "
        f"chunk of at most {CHUNK_SIZE} steps; median of {repeats}, each cold; "
        "peak mem by tracemalloc; scanspec: calculate + consume the same chunk)"
    )
    print()
    rows = [
        ("malcolm.scan.load (scan_points; no scanspec)", "import malcolm.scan.load"),
        ("numpy alone (most of the above)", "import numpy"),
        ("scanspec.specs (what it no longer pays)", "import scanspec.specs"),
    ]
    print(f"{'import, in a fresh interpreter':<46} {'measured':>10}")
    for name, statement in rows:
        print(f"{name:<46} {import_seconds(statement, repeats) * 1e3:>7.0f} ms")
    if stream_mib:
        rate, rss = points_streaming(stream_mib)
        print()
        print(
            f"malcolm points, 1e8-point snake grid: first {stream_mib} MiB of "
            f"output at {rate:.0f} MiB/s, peak RSS {rss:.0f} MiB (the whole "
            "output is about 14 GiB; target: memory independent of the size)"
        )


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument(
        "--stream-mib",
        type=int,
        default=64,
        metavar="MIB",
        help="MiB of malcolm points output to read (0: skip)",
    )
    args = parser.parse_args()
    main(args.repeats, args.stream_mib)

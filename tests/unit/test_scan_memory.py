"""A scan's points take memory in proportion to its dimensions, not to its
number of points: building and validating compute no point, `malcolm points`
streams, and scanspec is imported only when a Spec is used."""

from __future__ import annotations

import json
import resource
import subprocess
import sys
import tracemalloc
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from malcolm.core import PointGeneratorMeta
from malcolm.scan import ScanPoints, gda, scan_points
from malcolm.scan import compound as compound_module
from malcolm.scan.load import forget_built_scans

MIB = 1024 * 1024
ROI = "scanpointgenerator:roi/"


def held_bytes(obj: Any) -> int:
    """The bytes of every numpy array reachable from ``obj``'s attributes,
    lists, tuples and dicts (each array once)."""
    seen: set[int] = set()
    total = 0
    stack = [obj]
    while stack:
        item = stack.pop()
        if id(item) in seen:
            continue
        seen.add(id(item))
        if isinstance(item, np.ndarray):
            total += item.nbytes
        elif isinstance(item, dict):
            stack.extend(item.values())
        elif isinstance(item, list | tuple | set):
            stack.extend(item)
        elif hasattr(item, "__dict__") and not isinstance(item, type):
            stack.extend(vars(item).values())
    return total


def snake_grid(ny: int, nx: int, **kwargs: Any) -> dict[str, Any]:
    return gda.compound(
        gda.line("y", ny), gda.line("x", nx, alternate=True), duration=0.1, **kwargs
    )


def with_circle(data: dict[str, Any]) -> dict[str, Any]:
    circle = {"typeid": ROI + "CircularROI:1.0", "centre": [0.5, 0.5], "radius": 0.5}
    excluder = {
        "typeid": "scanpointgenerator:excluder/ROIExcluder:1.0",
        "axes": ["x", "y"],
        "rois": [circle],
    }
    return {**data, "excluders": [excluder]}


def test_a_1e8_point_snake_grid_holds_no_array_of_its_size():
    points = scan_points(snake_grid(10_000, 10_000))
    assert points.size == 100_000_000
    assert held_bytes(points) < 64 * 1024
    # the last steps: row 9999 runs backwards, so x ends where it started
    last = points.chunk(points.size - 3, points.size)
    assert last.positions["y"].tolist() == [1.0, 1.0, 1.0]
    assert last.positions["x"].tolist() == [2 / 9999, 1 / 9999, 0.0]
    assert last.lower["x"][-1] == 0.5 / 9999 and last.upper["x"][-1] == -0.5 / 9999
    assert last.duration.tolist() == [0.1] * 3
    assert points.steps_per_run(["x"]) == 10_000
    assert held_bytes(points) < 64 * 1024  # computing chunks keeps nothing


def test_a_grid_of_millions_holds_kilobytes():
    points = scan_points(snake_grid(2000, 2000))
    points.chunk(0, 4000)
    assert held_bytes(points) < 64 * 1024  # the whole scan's arrays: 190 MiB


def test_a_region_over_a_big_grid_holds_its_runs_not_its_points():
    points = scan_points(with_circle(snake_grid(2000, 2000)))
    assert len(points.dimensions) == 1 and 3_000_000 < points.size < 3_200_000
    # two runs a row at most, 16 bytes each; the kept indexes would be 25 MiB
    assert held_bytes(points) < 2000 * 2 * 16 + 1024


def test_a_1e6_point_spiral_holds_nothing_of_its_size():
    radius = ((1_000_000 - 0.5) / np.pi) ** 0.5
    points = scan_points(gda.compound(gda.spiral("x", "y", radius)))
    assert points.size == 1_000_000
    assert held_bytes(points) < 4096


def test_a_scanspec_grid_holds_its_dimensions_only():
    from scanspec.specs import Fly, Linspace

    points = scan_points(
        Fly(0.1 @ (Linspace("y", 0, 1, 10_000) * ~Linspace("x", 0, 1, 10_000)))
    )
    assert points.size == 100_000_000
    # positions, lower, upper and durations of 10,000 points, twice
    assert held_bytes(points) <= 2 * 4 * 10_000 * 8
    assert points.chunk(0, 2).upper["x"].tolist() == [0.5 / 9999, 1.5 / 9999]


def test_whole_arrays_are_computed_only_when_asked_for():
    points = scan_points(snake_grid(300, 300))
    assert held_bytes(points) < 4096
    assert points.positions["x"].shape == (90_000,)
    assert held_bytes(points) == 2 * 90_000 * 8  # kept: positions of y and x
    assert held_bytes(points.copy()) < 4096


def allocated_mib(call: Any) -> float:
    tracemalloc.start()
    try:
        call()
        return tracemalloc.get_traced_memory()[1] / MIB
    finally:
        tracemalloc.stop()


def test_validating_a_generator_computes_no_point():
    data = snake_grid(2000, 2000)
    meta = PointGeneratorMeta("generator")
    forget_built_scans()
    # every point's positions and bounds would be 190 MiB
    assert allocated_mib(lambda: meta.validate(data)) < 1


def test_validate_then_configure_builds_a_region_once(monkeypatch):
    calls = []
    real = compound_module.find_runs

    def counting(*args: Any, **kwargs: Any) -> Any:
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(compound_module, "find_runs", counting)
    forget_built_scans()
    data = with_circle(snake_grid(40, 40))
    PointGeneratorMeta("generator").validate(data)
    first = scan_points(json.loads(json.dumps(data)))  # the same content
    assert len(calls) == 1
    again = scan_points(data)
    assert len(calls) == 1
    assert first is not again and first.size == again.size
    assert first.positions["x"].tolist() == again.positions["x"].tolist()
    scan_points(with_circle(snake_grid(40, 41)))
    assert len(calls) == 2


def test_kept_scans_hold_no_whole_arrays():
    forget_built_scans()
    data = snake_grid(50, 50)
    scan_points(data).positions  # noqa: B018  (computed on the caller's copy)
    from malcolm.scan import load

    kept = list(load._built._scans.values())
    assert len(kept) == 1 and held_bytes(kept) < 4096


def run_limited(argv: list[str], limit_mib: int, read: int) -> tuple[bytes, int, str]:
    """Run ``argv`` with at most ``limit_mib`` MiB of address space; read the
    first ``read`` bytes of its output, then close it."""

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (limit_mib * MIB, limit_mib * MIB))

    child = subprocess.Popen(
        argv,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        preexec_fn=limit,
        env={"OPENBLAS_NUM_THREADS": "1", "PATH": "/usr/bin:/bin"},
    )
    assert child.stdout is not None and child.stderr is not None
    out = b""
    while len(out) < read:
        data = child.stdout.read(read - len(out))
        if not data:
            break
        out += data
    child.stdout.close()
    status = child.wait(timeout=120)
    err = child.stderr.read().decode()
    child.stderr.close()
    return out, status, err


def test_points_streams_a_1e8_point_scan_in_bounded_memory(tmp_path: Path):
    file = tmp_path / "big.json"
    file.write_text(json.dumps(snake_grid(10_000, 10_000)))
    # one whole-scan array alone would be 763 MiB
    out, status, err = run_limited(
        [sys.executable, "-m", "malcolm", "points", str(file)], 1024, 4 * MIB
    )
    assert len(out) == 4 * MIB, err
    assert out.startswith(
        b'{"axes": ["y", "x"], "size": 100000000, "shape": [10000, 10000], '
        b'"positions": {"y": [0.0, 0.0, '
    )
    assert status == 141 and err == ""  # ended by the closed pipe, quietly


@pytest.mark.parametrize(
    "data",
    [
        snake_grid(3, 4),
        with_circle(snake_grid(5, 6)),
        gda.compound(gda.spiral("x", "y", 2.0), duration=-1),
    ],
    ids=["snake", "region", "spiral"],
)
def test_points_output_is_the_whole_document(tmp_path: Path, data, capsys):
    from malcolm.cli import main

    file = tmp_path / "scan.json"
    file.write_text(json.dumps(data))
    assert main(["points", str(file)]) == 0
    out = capsys.readouterr().out
    points = scan_points(data)
    assert out == json.dumps(points.to_json(), allow_nan=False) + "\n"
    assert json.loads(out)["positions"]["x"] == points.positions["x"].tolist()


def test_scanspec_is_imported_only_for_a_spec():
    code = (
        "import sys\n"
        "from malcolm.scan import ScanPoints, gda, scan_points\n"
        "from malcolm.scan.files import points_from_file\n"
        "import malcolm.demo, malcolm.cli\n"
        "from malcolm.core import PointGeneratorMeta\n"
        "data = gda.compound(gda.line('y', 2), gda.line('x', 3))\n"
        "PointGeneratorMeta('g').validate(data)\n"
        "scan_points(data).chunk(0, 6)\n"
        "print(sorted(m for m in sys.modules if m.startswith('scanspec')))\n"
        "scan_points({'type': 'Linspace', 'axis': 'x', 'start': 0, 'stop': 1,"
        " 'num': 2})\n"
        "print('scanspec.specs' in sys.modules)\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.split("\n")[:2] == ["[]", "True"]


def test_a_scanpoints_is_returned_as_it_is():
    points = scan_points(snake_grid(2, 2))
    assert scan_points(points) is points
    assert isinstance(points, ScanPoints)

"""The ``malcolm points FILE`` command."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from scanspec.specs import Fly, Linspace

from malcolm.cli import build_parser, main

P = "scanpointgenerator:generator/"
KEYS = {"axes", "size", "shape", "positions", "lower", "upper", "duration"}

GENERATOR = {
    "typeid": P + "CompoundGenerator:1.0",
    "generators": [
        {
            "typeid": P + "LineGenerator:1.0",
            "axes": ["y"],
            "units": ["mm"],
            "start": [1],
            "stop": [3],
            "size": 2,
            "alternate": False,
        },
        {
            "typeid": P + "LineGenerator:1.0",
            "axes": ["x"],
            "units": ["mm"],
            "start": [0],
            "stop": [0.5],
            "size": 3,
            "alternate": True,
        },
    ],
    "excluders": [],
    "mutators": [],
    "duration": 0.5,
    "continuous": True,
    "delay_after": 0.0,
}
EXPECTED = {
    "axes": ["y", "x"],
    "size": 6,
    "shape": [2, 3],
    "positions": {
        "y": [1.0, 1.0, 1.0, 3.0, 3.0, 3.0],
        "x": [0.0, 0.25, 0.5, 0.5, 0.25, 0.0],
    },
    "lower": {
        "y": [1.0, 1.0, 1.0, 3.0, 3.0, 3.0],
        "x": [-0.125, 0.125, 0.375, 0.625, 0.375, 0.125],
    },
    "upper": {
        "y": [1.0, 1.0, 1.0, 3.0, 3.0, 3.0],
        "x": [0.125, 0.375, 0.625, 0.375, 0.125, -0.125],
    },
    "duration": [0.5] * 6,
}


@pytest.fixture
def generator_file(tmp_path: Path) -> Path:
    file = tmp_path / "scan.json"
    file.write_text(json.dumps(GENERATOR))
    return file


def test_points_prints_json(generator_file, capsys):
    assert main(["points", str(generator_file)]) == 0
    out, err = capsys.readouterr()
    assert err == ""
    assert json.loads(out) == EXPECTED


def test_points_from_yaml_scanspec(tmp_path, capsys):
    spec = Fly(0.5 @ (Linspace("y", 1, 3, 2) * ~Linspace("x", 0, 0.5, 3)))
    file = tmp_path / "spec.yaml"
    file.write_text(yaml.safe_dump(dict(spec.serialize())))
    assert main(["points", str(file)]) == 0
    data = json.loads(capsys.readouterr().out)
    assert set(data) == KEYS
    assert data["shape"] == [2, 3]
    assert data["positions"] == EXPECTED["positions"]
    assert data["upper"] == EXPECTED["upper"]


def test_points_step_scan_duration_is_null(tmp_path, capsys):
    file = tmp_path / "spec.json"
    file.write_text(json.dumps(dict(Linspace("x", 0, 1, 2).serialize())))
    assert main(["points", str(file)]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["duration"] is None
    assert data["lower"] == data["positions"] == {"x": [0.0, 1.0]}


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (
            {**GENERATOR, "generators": [{**GENERATOR["generators"][0], "size": -3}]},
            "generators[0].size: expected a positive integer, got -3",
        ),
        (
            {**GENERATOR, "excluders": [{"typeid": "x"}]},
            "excluders[0]: unknown typeid 'x'",
        ),
        ("{oops", "1: invalid JSON"),
    ],
)
def test_points_bad_file(tmp_path, capsys, content, message):
    file = tmp_path / "bad.json"
    file.write_text(content if isinstance(content, str) else json.dumps(content))
    assert main(["points", str(file)]) == 1
    out, err = capsys.readouterr()
    assert out == ""
    separator = ":" if message[0].isdigit() else ": "
    assert err.startswith(f"{file}{separator}{message}")
    assert "Traceback" not in err
    assert len(err.strip().splitlines()) == 1


def test_points_missing_file(tmp_path, capsys):
    file = tmp_path / "nope.yaml"
    assert main(["points", str(file)]) == 1
    assert capsys.readouterr().err.startswith(f"{file}: cannot read file")


def test_usage_errors_return_status(capsys):
    assert main([]) == 2
    assert "COMMAND" in capsys.readouterr().err
    assert main(["points"]) == 2
    assert main(["--help"]) == 0
    assert "points" in capsys.readouterr().out


def test_build_parser_dispatches_to_a_function():
    args = build_parser().parse_args(["points", "f.json"])
    assert args.file == "f.json"
    assert callable(args.func)


def _run(*argv: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        argv, capture_output=True, text=True, timeout=120, check=False
    )


def test_console_script(generator_file):
    script = Path(sys.executable).with_name("malcolm")
    if not script.exists():
        pytest.skip(f"console script not installed next to {sys.executable}")
    result = _run(str(script), "points", str(generator_file))
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout) == EXPECTED


def test_console_script_bad_file(tmp_path):
    script = Path(sys.executable).with_name("malcolm")
    if not script.exists():
        pytest.skip(f"console script not installed next to {sys.executable}")
    file = tmp_path / "bad.yaml"
    file.write_text("typeid: nope\n")
    result = _run(str(script), "points", str(file))
    assert result.returncode == 1
    assert result.stdout == ""
    assert result.stderr.strip() == (
        f"{file}:1: typeid: expected "
        f"'scanpointgenerator:generator/CompoundGenerator:1.0', got 'nope'"
    )


def test_python_dash_m(generator_file):
    result = _run(sys.executable, "-m", "malcolm", "points", str(generator_file))
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout) == EXPECTED

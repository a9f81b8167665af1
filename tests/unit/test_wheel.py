"""The wheel carries the models and the packaged definitions: built offline,
installed into a fresh venv and run from outside the checkout, `malcolm demo
--scan` works (issue 7 item 11)."""

from __future__ import annotations

import shutil
import subprocess
import sys
import sysconfig
import venv
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
#: what building the wheel reads from the checkout
SOURCES = ("malcolm", "models", "pyproject.toml", "setup.py", "README.md")


def run(*argv: str | Path, cwd: Path) -> subprocess.CompletedProcess[str]:
    result = subprocess.run(
        [str(a) for a in argv], cwd=cwd, capture_output=True, text=True, timeout=300
    )
    assert result.returncode == 0, result.stdout + result.stderr
    return result


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """The wheel, built from a copy of the checkout (which stays untouched)."""
    source = tmp_path_factory.mktemp("source")
    for name in SOURCES:
        path = ROOT / name
        if path.is_dir():
            ignore = shutil.ignore_patterns("__pycache__", "*.egg-info")
            shutil.copytree(path, source / name, ignore=ignore)
        else:
            shutil.copy(path, source / name)
    out = tmp_path_factory.mktemp("wheel")
    run(
        sys.executable,
        "-m",
        "pip",
        "wheel",
        "--no-build-isolation",
        "--no-deps",
        "--no-index",
        "-q",
        "-w",
        out,
        source,
        cwd=source,
    )
    (built,) = out.glob("malcolm-*.whl")
    return built


def test_the_wheel_holds_the_models_and_definitions(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    models = {p.name for p in (ROOT / "models").glob("*.yaml")}
    assert {f"malcolm/models/{m}" for m in models} <= names
    blocks = ROOT / "malcolm" / "blocks"
    for path in blocks.rglob("*.yaml"):
        assert f"malcolm/blocks/{path.relative_to(blocks).as_posix()}" in names


def test_demo_scan_runs_from_the_wheel_in_a_fresh_venv(wheel, tmp_path):
    fresh = tmp_path / "venv"
    venv.EnvBuilder(with_pip=False).create(fresh)
    python = fresh / "bin" / "python"
    run(
        sys.executable,
        "-m",
        "pip",
        "--python",
        python,
        "install",
        "--no-deps",
        "--no-index",
        "-q",
        wheel,
        cwd=tmp_path,
    )
    # the test venv's dependencies, by a plain path line: it adds the
    # directory but not the .pth files in it, so not the editable malcolm
    site = run(
        python,
        "-c",
        "import sysconfig; print(sysconfig.get_path('purelib'))",
        cwd=tmp_path,
    ).stdout.strip()
    ours = sysconfig.get_path("purelib")
    (Path(site) / "test-venv-dependencies.pth").write_text(ours + "\n")
    where = run(python, "-c", "import malcolm; print(malcolm.__file__)", cwd=tmp_path)
    assert where.stdout.strip().startswith(site)
    result = run(fresh / "bin" / "malcolm", "demo", "--scan", cwd=tmp_path)
    assert result.stdout.rstrip().endswith("SCAN Finished")
    assert "12/12" in result.stdout
    assert result.stderr == ""

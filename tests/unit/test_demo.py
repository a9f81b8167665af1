"""The demo process and the `malcolm demo` / `malcolm graph` commands."""

import subprocess
import sys
from pathlib import Path

from malcolm.cli import main


def test_demo_scan_runs_to_the_end_with_a_progress_bar(capsys):
    assert main(["demo", "--scan"]) == 0
    out = capsys.readouterr().out
    for mri in ("HELLO", "COUNTER", "MOTOR:X", "MOTOR:Y", "DET1", "DET2", "SCAN"):
        assert f"  {mri} " in out
    assert "12/12" in out
    assert out.rstrip().endswith("SCAN Finished")


def test_demo_command_installed_as_a_script():
    exe = Path(sys.executable).with_name("malcolm")
    result = subprocess.run(
        [str(exe), "demo", "--scan"], capture_output=True, text=True, timeout=60
    )
    assert result.returncode == 0, result.stderr
    assert "SCAN Finished" in result.stdout
    assert result.stderr == ""


def test_graph_prints_mermaid_and_dot(capsys):
    assert main(["graph", "runnable_device"]) == 0
    mermaid = capsys.readouterr().out
    assert mermaid.startswith("stateDiagram-v2")
    assert "Configuring --> Armed" in mermaid
    assert main(["graph", "stateful", "--format", "dot"]) == 0
    assert capsys.readouterr().out.startswith("digraph")


def test_graph_of_a_missing_model_is_an_error_not_a_traceback(capsys):
    assert main(["graph", "no_such_model"]) == 1
    err = capsys.readouterr().err
    assert "no_such_model" in err and "Traceback" not in err

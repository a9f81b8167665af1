"""Mermaid and Graphviz pictures of the models."""

from __future__ import annotations

from malcolm.fsm import load_model


def test_mermaid() -> None:
    text = load_model("runnable_device").to_mermaid()
    lines = text.splitlines()
    assert lines[0] == "stateDiagram-v2"
    assert "    [*] --> Disabled" in lines
    assert "    Disabled --> Resetting: init /Init" in lines
    assert "    Ready --> Configuring: configure /ReportStatus,Validate" in lines
    assert "    PostRun --> Finished: done [scan_complete] /PostRunReady" in lines
    assert "    Seeking --> Paused: done [is_paused] /Seek" in lines
    assert "    Armed --> Running: run" in lines
    (busy,) = [line.split() for line in lines if line.startswith("    class ")]
    assert set(busy[1].split(",")) == load_model("runnable_device").busy_states()
    assert busy[2] == "busy"
    assert "    Configuring : Parts configure their hardware for the scan" in lines
    assert text.endswith("\n")


def test_dot() -> None:
    model = load_model("stateful")
    text = model.to_dot()
    assert text.startswith('digraph "Stateful" {')
    assert text.rstrip().endswith("}")
    assert '"__initial__" -> "Disabled";' in text
    assert '"Resetting" -> "Ready" [label="done /Reset"];' in text
    assert '"Disabled" -> "Resetting" [label="init /Init"];' in text
    resetting = next(
        line for line in text.splitlines() if line.strip().startswith('"Resetting" [')
    )
    assert "dashed" in resetting
    ready = next(
        line for line in text.splitlines() if line.strip().startswith('"Ready" [')
    )
    assert "dashed" not in ready
    assert text.count(" -> ") == len(model.transitions) + 1


def test_unless_guards_and_quotes_in_labels(tmp_path) -> None:
    path = tmp_path / "m.yaml"
    path.write_text(
        "name: M\ninitial: A\nstates:\n"
        '  A: {description: the "first" one}\n  B: {}\n'
        "transitions:\n"
        "  - {trigger: go, source: A, dest: B, guards: [ok], unless: [stuck]}\n"
    )
    model = load_model(path)
    assert "    A --> B: go [ok, !stuck]" in model.to_mermaid().splitlines()
    dot = model.to_dot()
    assert '[label="go [ok, !stuck]"]' in dot
    assert 'tooltip="the \\"first\\" one"' in dot

"""Building many blocks of one kind does the per-kind work once (issue 8):
its files are parsed, and its classes' signatures read, once however many
blocks are made."""

from __future__ import annotations

import inspect
from pathlib import Path

import pytest

from malcolm import yamlio
from malcolm.config.build import build_process


def box_process(tmp_path: Path, blocks: int) -> Path:
    """A process file of ``blocks`` blocks of a definition of 10 attributes."""
    (tmp_path / "bench").mkdir(exist_ok=True)
    (tmp_path / "bench" / "Box.yaml").write_text(
        "".join(f"ca.Double:\n    name: a{i}\n    pv: BOX:A{i}\n\n" for i in range(10))
    )
    path = tmp_path / f"process{blocks}.yaml"
    path.write_text(
        "".join(f"block.bench.Box:\n    mri: BOX{i}\n\n" for i in range(blocks))
    )
    return path


def counted(monkeypatch: pytest.MonkeyPatch, owner: object, name: str) -> list[int]:
    calls: list[int] = []
    real = getattr(owner, name)

    def spy(*args, **kwargs):
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(owner, name, spy)
    return calls


def test_per_kind_work_does_not_grow_with_the_blocks(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    build_process(box_process(tmp_path, 1), [tmp_path])  # the first of its kind
    signatures = counted(monkeypatch, inspect, "signature")
    parses = counted(monkeypatch, yamlio, "load")
    few = box_process(tmp_path, 3)
    many = box_process(tmp_path, 30)
    build_process(few, [tmp_path])
    after_few = (len(signatures), len(parses))
    process = build_process(many, [tmp_path])
    after_many = (len(signatures) - after_few[0], len(parses) - after_few[1])
    assert len(process.mris) == 30
    assert after_many == after_few == (0, 0)

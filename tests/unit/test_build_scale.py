"""Building many blocks of one kind does the per-kind work once (issue 8):
its files are parsed, and its classes' signatures read, once however many
blocks are made; ``long_lived`` keeps the collector off what a server keeps."""

from __future__ import annotations

import asyncio
import gc
import inspect
from pathlib import Path

import pytest

from malcolm import yamlio
from malcolm.config.build import build_process
from malcolm.core import long_lived


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


def test_long_lived_pauses_the_collector_then_freezes(tmp_path: Path) -> None:
    path = box_process(tmp_path, 5)
    assert gc.isenabled()
    frozen = gc.get_freeze_count()
    try:
        with long_lived():
            assert not gc.isenabled()
            process = build_process(path, [tmp_path])
        assert gc.isenabled()
        assert gc.get_freeze_count() > frozen
        asyncio.run(_start_stop(process))
    finally:
        gc.unfreeze()


async def _start_stop(process) -> None:
    await process.start()
    assert all(process.get_block(m).state.value == "Ready" for m in process.mris)
    await process.stop()


def test_long_lived_freezes_nothing_after_an_error() -> None:
    frozen = gc.get_freeze_count()
    with pytest.raises(ValueError), long_lived():
        raise ValueError("no")
    assert gc.isenabled()
    assert gc.get_freeze_count() == frozen


def test_long_lived_leaves_a_disabled_collector_disabled() -> None:
    gc.disable()
    try:
        with long_lived():
            pass
        assert not gc.isenabled()
    finally:
        gc.enable()
        gc.unfreeze()

"""Saving a design is atomic: a crash at any moment leaves the old or the new one.

The kill test runs ``atomic_save_child.py`` in a child Python process that
saves two big designs (A: thousands of small records; B: long strings, floats
and a 2000-row table) over and over, and SIGKILLs it at random moments, many
times. After each kill the design file must be, byte for byte, the text of A
or of B (and it parses with ``load_design`` to exactly A's or B's records;
each distinct text is parsed once), and ``names()`` lists only the design,
never a temporary file. Two modes: ``store`` goes through
``DesignStore.save`` (mostly dumping YAML, then the atomic write); ``write``
only replaces the file with ``atomic_write``, so that most kills land in the
middle of a write (the test checks that some did, leaving a temporary file).
"""

from __future__ import annotations

import asyncio
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from malcolm.controllers.manager import ManagerController
from malcolm.controllers.stateful import StatefulController
from malcolm.core import BadValueError, NumberMeta, Process
from malcolm.editor import store as store_module
from malcolm.editor.store import DesignStore, atomic_write, dump_design
from malcolm.parts import ChildPart, Part
from malcolm.parts.design import FixedInt, ModelPart, PalettePart, load_design

from .atomic_save_child import MRI, NAME, design_a, design_b

CHILD = Path(__file__).with_name("atomic_save_child.py")
ROOT = Path(__file__).resolve().parent.parent.parent
KILLS = 30
EXAMPLE = Path(__file__).parent / "config_fixtures" / "designs" / "PositionBased.yaml"


def _spawn(designs_dir: Path, mode: str, first: int) -> subprocess.Popen[str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        p for p in (str(ROOT), env.get("PYTHONPATH", "")) if p
    )
    return subprocess.Popen(
        [sys.executable, str(CHILD), str(designs_dir), mode, str(first)],
        stdout=subprocess.PIPE,
        text=True,
        env=env,
        cwd=ROOT,
    )


def _slowest_save(designs: list[list[Any]], tmp: Path) -> float:
    """How long a save of the bigger design takes here (to spread the kills)."""
    store = DesignStore(MRI, tmp / "calibrate")
    times = []
    for records in designs:
        t0 = time.perf_counter()
        store.save(NAME, records)
        times.append(time.perf_counter() - t0)
    return max(times)


@pytest.mark.parametrize("mode", ["store", "write"])
def test_sigkill_during_save_leaves_the_old_or_the_new_design(
    tmp_path: Path, mode: str
) -> None:
    designs = [design_a(), design_b()]
    texts = [dump_design(d) for d in designs]
    assert len(texts[0]) != len(texts[1])
    parsed: dict[str, int] = {}
    for k, text in enumerate(texts):  # what the child writes in "write" mode
        atomic_write(tmp_path / "texts" / f"{k}.yaml", text)

    store = DesignStore(MRI, tmp_path)
    store.save(NAME, designs[0])  # what the file holds before the first kill
    path = store.dir / f"{NAME}.yaml"
    current = 0
    if mode == "store":
        # kill anywhere in the first two saves
        low, high = 0.005, max(0.05, 2 * _slowest_save(designs, tmp_path))
    else:
        low, high = 0.005, 0.05
    rng = random.Random()
    seen = [0, 0]
    mid_write = 0
    for round_ in range(KILLS):
        first = round_ % 2
        proc = _spawn(tmp_path, mode, first)
        try:
            assert proc.stdout is not None
            assert proc.stdout.readline() == "ready\n", "the child did not start"
            time.sleep(rng.uniform(low, high))
        finally:
            proc.send_signal(signal.SIGKILL)
            out, _ = proc.communicate(timeout=30)
        assert proc.returncode == -signal.SIGKILL, out
        saved = [int(line.split()[1]) for line in out.splitlines() if line]

        text = path.read_text(encoding="utf-8")
        if text not in texts:
            load_design(path)  # a parse error says more than a diff
            pytest.fail(f"round {round_}: {path} is neither design A nor design B")
        k = texts.index(text)
        if text not in parsed:
            records = load_design(path).records
            assert records == designs[k], f"design {'AB'[k]} did not read back"
            parsed[text] = k
        if not saved:  # killed during its first save: the old one, or that one
            assert k in (current, first), (round_, k, current, first)
        current = k
        seen[k] += 1

        assert store.names() == [NAME], store.names()
        others = [p.name for p in store.dir.iterdir() if p != path]
        for name in others:
            assert name.startswith(f".{NAME}.yaml.") and name.endswith(".tmp"), name
        if len(others) > mid_write:
            mid_write = len(others)  # temporaries of killed writes pile up

    if mode == "write":
        assert mid_write > 0, "no kill landed in the middle of a write"
    print(f"{mode}: {KILLS} kills, A {seen[0]}, B {seen[1]}, {mid_write} mid-write")


# --------------------------------------------------------------------------
# atomic_write


def test_atomic_write_replaces_the_file_whole(tmp_path: Path) -> None:
    path = tmp_path / "d.yaml"
    path.write_text("old\n")
    before = path.stat().st_ino
    atomic_write(path, "new text\n" * 1000)
    assert path.read_text() == "new text\n" * 1000
    assert path.stat().st_ino != before  # a new file took its place
    assert [p.name for p in tmp_path.iterdir()] == ["d.yaml"]


def test_atomic_write_makes_the_directory(tmp_path: Path) -> None:
    path = tmp_path / "a" / "b" / "d.yaml"
    atomic_write(path, "x: 1\n")
    assert path.read_text() == "x: 1\n"


def test_atomic_write_that_fails_to_write_leaves_the_old_file_and_no_temp(
    tmp_path: Path,
) -> None:
    path = tmp_path / "d.yaml"
    path.write_text("old\n")
    with pytest.raises(UnicodeEncodeError):
        atomic_write(path, "half written \udc80 never")  # a lone surrogate
    assert path.read_text() == "old\n"
    assert [p.name for p in tmp_path.iterdir()] == ["d.yaml"]


def test_atomic_write_that_fails_to_replace_leaves_the_old_file_and_no_temp(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "d.yaml"
    path.write_text("old\n")

    def refuse(src: Any, dst: Any) -> None:
        raise PermissionError(f"cannot replace {dst}")

    monkeypatch.setattr(store_module.os, "replace", refuse)
    with pytest.raises(PermissionError):
        atomic_write(path, "new\n")
    assert path.read_text() == "old\n"
    assert [p.name for p in tmp_path.iterdir()] == ["d.yaml"]


def test_atomic_write_interrupted_leaves_no_temp(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A KeyboardInterrupt (BaseException) in the middle cleans up too."""
    path = tmp_path / "d.yaml"

    def interrupt(fd: int) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(store_module.os, "fsync", interrupt)
    with pytest.raises(KeyboardInterrupt):
        atomic_write(path, "new\n")
    assert list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------------
# names and templates


def _template_store(tmp_path: Path) -> DesignStore:
    templates = tmp_path / "templates"
    templates.mkdir()
    (templates / "example.yaml").write_bytes(EXAMPLE.read_bytes())
    return DesignStore("Z", tmp_path / "designs", [templates])


def test_a_template_is_read_only(tmp_path: Path) -> None:
    store = _template_store(tmp_path)
    records = [ModelPart("Mine"), FixedInt("PCOMP1.WIDTH", 3)]
    assert store.names() == ["example"] and store.is_template("example")
    with pytest.raises(BadValueError, match="read-only template"):
        store.save("example", records)
    with pytest.raises(BadValueError, match="read-only template"):
        store.check_writable("example")
    assert (tmp_path / "templates" / "example.yaml").read_bytes() == (
        EXAMPLE.read_bytes()
    )
    assert not store.dir.exists()  # nothing written anywhere
    assert store.load("example").model == "PositionBased"
    # under another name it saves, and the template is still listed after it
    store.save("mine", records)
    assert store.names() == ["mine", "example"]
    assert store.load("mine").records == records


@pytest.mark.parametrize("name", ["", "a b", "../evil", ".hidden", "x/y", "-x"])
def test_a_bad_name_is_refused_and_nothing_written(tmp_path: Path, name: str) -> None:
    store = _template_store(tmp_path)
    with pytest.raises(BadValueError, match="not a design name"):
        store.save(name, [ModelPart("M")])
    assert sorted(p.name for p in tmp_path.rglob("*")) == [
        "example.yaml",
        "templates",
    ]


# --------------------------------------------------------------------------
# the manager refuses a bad save before leaving Ready


class _Soft(Part):
    def setup(self, registrar: Any) -> None:
        registrar.add_attribute("WIDTH", NumberMeta("int32", writeable=True), 5)


async def _manager_save_refusals(tmp_path: Path) -> None:
    templates = tmp_path / "templates"
    atomic_write(
        templates / "tiny.yaml",
        dump_design(
            [ModelPart("Tiny"), PalettePart("C", 1, 2, True), FixedInt("C.WIDTH", 7)]
        ),
    )
    process = Process("t")
    process.add_controller(StatefulController("Z:C", [_Soft("soft")]))
    manager = ManagerController(
        "Z",
        [ChildPart("C", "Z:C")],
        designs_dir=tmp_path / "designs",
        template_dirs=[templates],
    )
    process.add_controller(manager)
    await process.start()
    try:
        for name, why in [
            ("tiny", "read-only template"),
            ("a b", "not a design name"),
            ("", "name the design"),
        ]:
            with pytest.raises(BadValueError, match=why):
                await process.post(["Z", "save"], {"design": name})
            assert manager.current == "Ready", (name, manager.current)
        await process.put(["Z", "design"], "tiny")
        with pytest.raises(BadValueError, match="read-only template"):
            await process.post(["Z", "save"], {})  # the loaded one: a template
        assert manager.current == "Ready"
        await process.post(["Z", "save"], {"design": "kept"})
        assert manager.current == "Ready"
        assert manager.store is not None
        assert manager.store.names() == ["kept", "tiny"]
        assert load_design(manager.store.dir / "kept.yaml").records == [
            ModelPart("Tiny"),
            PalettePart("C", 1, 2, True),
            FixedInt("C.WIDTH", 7),
        ]
    finally:
        await process.stop()


def test_manager_refuses_a_bad_or_template_name_and_stays_ready(
    tmp_path: Path,
) -> None:
    asyncio.run(_manager_save_refusals(tmp_path))


def test_temps_of_saves_killed_long_ago_are_cleaned_up(tmp_path):
    import os
    import time

    from malcolm.editor.store import STALE_TEMP_SECONDS, atomic_write

    target = tmp_path / "d.yaml"
    old = tmp_path / ".d.yaml.abc123.tmp"
    fresh = tmp_path / ".d.yaml.def456.tmp"
    old.write_text("half a design")
    fresh.write_text("a save in progress")
    long_ago = time.time() - STALE_TEMP_SECONDS - 5
    os.utime(old, (long_ago, long_ago))
    atomic_write(target, "parts.ModelPart:\n    name: X\n")
    assert target.read_text() == "parts.ModelPart:\n    name: X\n"
    assert not old.exists()
    assert fresh.exists()

"""Models and block definitions are parsed once per process and shared
(issue 8): a thousand blocks of one kind read its files once, and a file
changed on disk is read again."""

from __future__ import annotations

import os
import textwrap
from pathlib import Path

import pytest

from malcolm import yamlio
from malcolm.config import find_definition, load_definition
from malcolm.config.definitions import _read_definition
from malcolm.controllers.runnable import RunnableController
from malcolm.controllers.stateful import StatefulController
from malcolm.fsm import ModelError, clear_model_cache, load_model

BASE = """\
name: Base
initial: Idle
states:
  Idle: {busy: false}
  Working: {busy: true}
phases:
  Work: the work
transitions:
  - {trigger: start, source: Idle, dest: Working}
  - {trigger: done, source: Working, dest: Idle, phases: [Work]}
methods:
  start: [Idle]
"""

CHILD = """\
name: Child
extends: base
phases:
  Tidy: tidy up
transitions:
  - {trigger: tidy, source: Idle, dest: Working, phases: [Tidy]}
"""


def write(path: Path, text: str) -> Path:
    path.write_text(textwrap.dedent(text))
    return path


@pytest.fixture
def parses(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """The files the YAML reader parses from now on."""
    seen: list[str] = []
    real = yamlio.load

    def load(path, text=None):
        seen.append(Path(path).name)
        return real(path, text)

    monkeypatch.setattr(yamlio, "load", load)
    return seen


def test_blocks_share_one_model_read_once(parses: list[str]) -> None:
    first = RunnableController("A")
    parses.clear()
    others = [RunnableController(f"B{i}") for i in range(5)]
    others += [StatefulController(f"S{i}") for i in range(5)]
    assert parses == []  # nothing parsed again
    assert all(c.model is first.model for c in others[:5])
    assert all(c.model is others[5].model for c in others[5:])
    assert load_model("runnable_device") is first.model


def test_a_shared_model_cannot_be_changed() -> None:
    model = load_model("stateful")
    with pytest.raises(AttributeError, match="read-only"):
        model.initial = "Ready"  # type: ignore[misc]
    with pytest.raises(TypeError):
        model.states["Extra"] = model.states["Ready"]  # type: ignore[index]
    with pytest.raises(TypeError):
        model.methods["reset"] = frozenset()  # type: ignore[index]
    with pytest.raises(AttributeError):
        model.transitions.append(model.transitions[0])  # type: ignore[attr-defined]
    # what a caller gets from a query is its own to change
    moves = model.transitions_for("reset", "Fault")
    moves.clear()
    assert model.transitions_for("reset", "Fault")


def test_a_changed_model_file_is_read_again(tmp_path: Path) -> None:
    path = write(tmp_path / "base.yaml", BASE)
    before = load_model(path)
    assert load_model(path) is before
    stamp = os.stat(path)
    # the same size and modification time: only the bytes tell
    write(path, BASE.replace("Idle", "Rest"))
    os.utime(path, ns=(stamp.st_atime_ns, stamp.st_mtime_ns))
    after = load_model(path)
    assert after is not before
    assert after.initial == "Rest"


def test_a_changed_parent_is_read_again(tmp_path: Path) -> None:
    base = write(tmp_path / "base.yaml", BASE)
    child = write(tmp_path / "child.yaml", CHILD)
    before = load_model(child)
    assert load_model(child) is before
    write(base, BASE.replace("the work", "other work"))
    after = load_model(child)
    assert after is not before
    assert after.phases["Work"] == "other work"
    assert after.parent is load_model(base)


def test_a_new_parent_earlier_on_the_search_path_is_used(tmp_path: Path) -> None:
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    write(tmp_path / "b" / "base.yaml", BASE)
    child = write(tmp_path / "child.yaml", CHILD)
    search = [tmp_path / "a", tmp_path / "b"]
    before = load_model(child, search)
    write(tmp_path / "a" / "base.yaml", BASE.replace("the work", "first"))
    after = load_model(child, search)
    assert after.phases["Work"] == "first"
    assert before.phases["Work"] == "the work"


def test_a_model_with_problems_is_reported_every_time(
    tmp_path: Path, parses: list[str]
) -> None:
    path = write(tmp_path / "bad.yaml", BASE.replace("initial: Idle", "initial: No"))
    for _ in range(2):
        with pytest.raises(ModelError, match="bad.yaml"):
            load_model(path)
    assert parses == ["bad.yaml", "bad.yaml"]


def test_a_parent_that_became_a_cycle_is_reported(tmp_path: Path) -> None:
    base = write(tmp_path / "base.yaml", BASE)
    child = write(tmp_path / "child.yaml", CHILD)
    load_model(child)
    write(base, BASE + "extends: child\n")
    with pytest.raises(ModelError, match="extends cycle"):
        load_model(child)


def test_clearing_the_cache_reads_again(parses: list[str]) -> None:
    load_model("stateful")
    parses.clear()
    clear_model_cache()
    load_model("stateful")
    assert parses == ["stateful.yaml"]


# ---- definitions


def test_definitions_are_read_once(monkeypatch: pytest.MonkeyPatch) -> None:
    read: list[str] = []

    def counting(path, name):
        read.append(path.name)
        return _read_definition(path, name)

    path = find_definition("demo.Motor")
    first = load_definition(path, name="demo.Motor")
    monkeypatch.setattr("malcolm.config.definitions._read_definition", counting)
    again = [load_definition(path, name="demo.Motor") for _ in range(3)]
    assert read == []
    assert all(d is first for d in again)
    assert isinstance(first.sections, tuple) and isinstance(first.params, tuple)


def test_a_changed_definition_is_read_again(tmp_path: Path) -> None:
    path = write(tmp_path / "Box.yaml", "ca.Double:\n    name: a\n    pv: BOX:A\n")
    before = load_definition(path)
    assert load_definition(path) is before
    write(path, "ca.Double:\n    name: b\n    pv: BOX:B\n")
    after = load_definition(path)
    assert [s.params["name"] for s in after.sections] == ["b"]


def test_the_cache_keeps_the_most_recently_used(tmp_path: Path) -> None:
    from malcolm.filecache import FileCache, Snapshot

    cache: FileCache[str] = FileCache(size=2)
    paths = [write(tmp_path / f"{n}.txt", n) for n in "abc"]
    for path in paths[:2]:
        snapshot = Snapshot.take(path)
        assert snapshot is not None
        cache.put(path.name, snapshot, path.stem)
    assert cache.get("a.txt") == "a"  # a is now more recent than b
    snapshot = Snapshot.take(paths[2])
    assert snapshot is not None
    cache.put("c.txt", snapshot, "c")
    assert (cache.get("a.txt"), cache.get("b.txt"), cache.get("c.txt")) == (
        "a",
        None,
        "c",
    )
    paths[0].unlink()
    assert cache.get("a.txt") is None and len(cache) == 1

"""Find model files, load what they extend, and report every problem.

Models are parsed once per process: a loaded model is kept
(:mod:`malcolm.filecache`) and the same, read-only :class:`Model` is handed
to every controller that asks for it, until its file (or a file it extends)
changes on disk.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from malcolm import yamlio
from malcolm.filecache import FileCache, Snapshot
from malcolm.yamlio import LineDict

from .errors import ModelError, Problem
from .model import Model
from .reader import ModelReader


def builtin_models_dir() -> Path:
    """The builtin models: ``$MALCOLM_MODELS_DIR`` when set (to run the
    conformance tests on edited copies of the builtin models), else
    ``malcolm/models`` in an installed wheel, else the ``models/`` directory
    next to the ``malcolm`` package (a checkout)."""
    override = os.environ.get("MALCOLM_MODELS_DIR")
    if override:
        return Path(override)
    import malcolm

    package = Path(malcolm.__file__).resolve().parent
    packaged = package / "models"
    return packaged if packaged.is_dir() else package.parent / "models"


def model_names() -> list[str]:
    """The stems of the builtin model files, sorted."""
    return sorted(p.stem for p in builtin_models_dir().glob("*.yaml"))


def load_model(name_or_path: str | Path, search: Sequence[Path] = ()) -> Model:
    """Load a model by file stem (looked up in ``search``, then the builtin
    ``models/``) or by path, with everything it extends.

    Raises :class:`ModelError` listing every problem found, each with its
    ``file:line``.
    """
    dirs = tuple(Path(d) for d in search)
    text = str(name_or_path)
    if isinstance(name_or_path, Path) or "/" in text or text.endswith(".yaml"):
        path = Path(name_or_path)
        if not path.is_file():
            raise ModelError([Problem(text, None, "no such model file")])
    else:
        found = _find(text, dirs)
        if found is None:
            places = ", ".join(str(d) for d in (*dirs, builtin_models_dir()))
            raise ModelError([Problem(f"{text}.yaml", None, f"not found in {places}")])
        path = found
    with _CACHE.lock:
        return _load(path, dirs, chain=())


def clear_model_cache() -> None:
    """Forget every loaded model: the next load reads its files again."""
    _CACHE.clear()


def _find(stem: str, dirs: Sequence[Path]) -> Path | None:
    for d in (*dirs, builtin_models_dir()):
        candidate = d / f"{stem}.yaml"
        if candidate.is_file():
            return candidate
    return None


def _read(path: Path) -> tuple[object, list[Problem]]:
    """The document at ``path`` and its problems, read by :mod:`malcolm.yamlio`."""
    try:
        data, found = yamlio.load(path)
    except yamlio.YamlError as e:
        found, data = [e.problem], None
    return data, [Problem(p.file, p.line, p.message) for p in found]


@dataclass(frozen=True)
class _Loaded:
    """A loaded model and the file its ``extends`` resolved to."""

    extends: str | None  # the ``extends`` value, if any
    parent_path: Path | None  # the parent's file, resolved
    model: Model


#: loaded models by (file as given, file resolved, search directories). An
#: entry is used again only while its file is unchanged and its ``extends``
#: still resolves to the same file, whose model (loaded the same way) is the
#: very parent the entry was built on. A model with problems is not kept: it
#: is read again, and reports them again, every time.
_CACHE: FileCache[_Loaded] = FileCache()


def _cached(
    key: tuple[str, Path, tuple[Path, ...]],
    path: Path,
    search: tuple[Path, ...],
    chain: tuple[Path, ...],
) -> Model | None:
    """The model kept for ``key`` if it is still what loading would give."""
    loaded = _CACHE.get(key)
    if loaded is None:
        return None
    if loaded.extends is None:
        return loaded.model
    found = _find_parent(path, loaded.extends, search)
    if found is None or found.resolve() != loaded.parent_path:
        return None
    if loaded.parent_path in (*chain, key[1]):
        return None  # now a cycle: let the reader report it
    try:
        parent = _load(found, search, (*chain, key[1]))
    except ModelError:
        return None
    return loaded.model if parent is loaded.model.parent else None


def _load(path: Path, search: tuple[Path, ...], chain: tuple[Path, ...]) -> Model:
    key = (str(path), path.resolve(), search)
    model = _cached(key, path, search, chain)
    if model is not None:
        return model
    snapshot = Snapshot.take(path)
    model, extends = _parse(path, search, chain)
    if snapshot is not None:
        parent = model.parent.path.resolve() if model.parent is not None else None
        _CACHE.put(key, snapshot, _Loaded(extends, parent, model))
    return model


def _parse(
    path: Path, search: tuple[Path, ...], chain: tuple[Path, ...]
) -> tuple[Model, str | None]:
    """Read ``path`` (and what it extends) into a Model; also its ``extends``."""
    data, problems = _read(path)
    if data is None:
        raise ModelError(problems or [Problem(str(path), 1, "the model file is empty")])
    reader = ModelReader(path, problems)
    if not reader.check_top(data):
        raise ModelError(problems)
    parent = None
    if "extends" in data:
        parent = _load_parent(path, data, search, chain, problems)
        if parent is None:
            # reading on would only repeat the parent's problems
            raise ModelError(problems)
    model = reader.read(data, parent)
    if problems:
        raise ModelError(problems)
    return model, data["extends"] if parent is not None else None


def _load_parent(
    path: Path,
    data: LineDict,
    search: tuple[Path, ...],
    chain: tuple[Path, ...],
    problems: list[Problem],
) -> Model | None:
    line = data.line_of("extends")
    stem = data["extends"]
    if not isinstance(stem, str) or not stem:
        problems.append(
            Problem(str(path), line, "extends must be the file stem of another model")
        )
        return None
    found = _find_parent(path, stem, search)
    if found is None:
        places = ", ".join(str(d) for d in (path.parent, *search, builtin_models_dir()))
        problems.append(
            Problem(str(path), line, f"extends {stem!r}: no {stem}.yaml in {places}")
        )
        return None
    here = (*chain, path.resolve())
    if found.resolve() in here:
        cycle = " -> ".join(p.name for p in (*here, found))
        problems.append(Problem(str(path), line, f"extends cycle: {cycle}"))
        return None
    try:
        return _load(found, search, here)
    except ModelError as e:
        problems.extend(e.problems)
        return None


def _find_parent(path: Path, stem: str, search: Sequence[Path]) -> Path | None:
    """The parent's file: next to the child first, then ``search``, then the
    builtin models. A stem with a suffix or a slash is a path from the child."""
    if stem.endswith((".yaml", ".yml")) or "/" in stem:
        candidate = path.parent / stem
        return candidate if candidate.is_file() else None
    candidate = path.parent / f"{stem}.yaml"
    if candidate.is_file():
        return candidate
    return _find(stem, search)

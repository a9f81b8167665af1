"""Which files ``malcolm check`` reads, and where it looks for definitions."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path

__all__ = ["default_search_path", "expand_files"]


def default_search_path(path: Path, extra: Sequence[str] = ()) -> list[str]:
    """Where definitions named in ``path`` are looked for (after
    ``malcolm/blocks``): the ``extra`` directories, then a ``blocks/``
    directory next to the file or next to its directory, then the
    directory a definition's own ``Module.Name`` implies (two levels up).
    """
    dirs = [str(d) for d in extra]
    here = path.resolve().parent
    cwd = Path.cwd()
    for d in (here / "blocks", here.parent / "blocks", here.parent, here):
        if d.is_dir():
            name = str(d.relative_to(cwd)) if d.is_relative_to(cwd) else str(d)
            if name not in dirs:
                dirs.append(name)
    return dirs


def expand_files(paths: Iterable[str]) -> list[str]:
    """``paths`` with each directory replaced by the YAML files under it
    (sorted; a directory with none stays, to be reported)."""
    files: list[str] = []
    for p in paths:
        if not p:  # Path("") would be the working directory
            files.append(p)
            continue
        path = Path(p)
        found = []
        try:
            if path.is_dir():
                found = sorted(
                    str(f)
                    for pattern in ("*.yaml", "*.yml")
                    for f in path.rglob(pattern)
                    if f.is_file()
                )
        except OSError:
            found = []
        files += found or [str(p)]
    return files

"""Build a Process from a process file (the blocks it lists, not started)."""

from __future__ import annotations

from collections.abc import Iterable

from malcolm.core import Process


def from_file(
    path: str, search_path: Iterable[str] = (), process: Process | None = None
) -> Process:
    """Build (not start) a Process from a process file.

    Raises :class:`~malcolm.config.ConfigError` listing every problem.
    """
    try:
        from malcolm.config.build import build_process
    except ImportError as e:  # pragma: no cover - until the builder exists
        from malcolm.config import expand_process, load_process_file

        # still report the file's own problems first
        expand_process(load_process_file(path, tuple(search_path)), search_path)
        raise RuntimeError(
            f"cannot build processes from files: {e} (malcolm.config.build)"
        ) from None
    return build_process(path, search_path=tuple(search_path), process=process)

"""``malcolm check``'s output: one line per problem, a summary, a status."""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import TextIO

from .checks import check_file
from .files import expand_files

__all__ = ["run_check"]


def _emit(line: str, stream: TextIO) -> None:
    """Write a line even if the stream cannot encode every character."""
    try:
        stream.write(line + "\n")
    except UnicodeEncodeError:
        encoding = getattr(stream, "encoding", None) or "ascii"
        stream.write(line.encode(encoding, "backslashreplace").decode(encoding) + "\n")


def run_check(
    files: Sequence[str],
    search_path: Sequence[str] = (),
    kind: str | None = None,
    verbose: bool = False,
    out: TextIO | None = None,
    err: TextIO | None = None,
) -> int:
    """Check ``files``: problems to ``out``, a summary to ``err``; 1 if any."""
    out = out or sys.stdout
    err = err or sys.stderr
    bad = total = 0
    files = expand_files(files)
    for f in files:
        result = check_file(f, search_path, kind)
        for problem in result.problems:
            _emit(str(problem), out)
        total += len(result.problems)
        bad += not result.ok
        if verbose:
            status = "ok" if result.ok else f"{_count(len(result.problems))}"
            _emit(f"{f}: {status} ({result.kind or 'unreadable'})", err)
    out.flush()
    n = len(files)
    if total:
        _emit(f"malcolm check: {_count(total)} in {bad} of {_files(n)}", err)
        return 1
    _emit(f"malcolm check: {_files(n)} OK", err)
    return 0


def _count(n: int) -> str:
    return f"{n} problem" + ("" if n == 1 else "s")


def _files(n: int) -> str:
    return f"{n} file" + ("" if n == 1 else "s")

"""What checking finds: a :class:`Finding` per problem, a :class:`CheckResult`
per file."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

__all__ = ["CheckResult", "Finding", "findings_of"]


@dataclass(frozen=True)
class Finding:
    """One problem: ``file:line: message`` (``file: message`` with no line)."""

    file: str
    line: int | None
    message: str

    def __str__(self) -> str:
        message = self.message.replace("\r", "\\r").replace("\n", "\\n")
        message = message.strip() or "(no message)"
        file = self.file or "<unknown>"
        if self.line is None:
            return f"{file}: {message}"
        return f"{file}:{self.line}: {message}"


@dataclass
class CheckResult:
    """What checking one file found."""

    file: str
    kind: str | None  #: one of KINDS, or None if the file could not be read
    problems: list[Finding] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.problems


def findings_of(error: Any, default_file: str) -> list[Finding]:
    """The problems of a ConfigError or ModelError (or a list of problems)
    as findings; a problem without a file is ``default_file``'s."""
    is_list = isinstance(error, list)
    problems: Iterable[Any] = (
        error if is_list else getattr(error, "problems", None) or []
    )
    out = [
        Finding(
            str(getattr(p, "file", "") or default_file),
            getattr(p, "line", None),
            str(getattr(p, "message", p)),
        )
        for p in problems
    ]
    return out if out or is_list else [Finding(default_file, None, str(error))]

"""Errors of the definition language: every problem names a file and a line.

A :class:`ConfigError` carries one or more :class:`Problem` objects, so that a
loader can report everything wrong with a file at once instead of stopping at
the first mistake. ``str(error)`` gives one ``file:line: message`` per line,
the format compilers use, which editors know how to jump to.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass


@dataclass(frozen=True)
class Problem:
    """One thing wrong with a configuration file, at a 1-based line."""

    file: str
    line: int
    message: str

    def __str__(self) -> str:
        message = self.message.replace("\r", "\\r").replace("\n", "\\n")
        return f"{self.file}:{self.line}: {message}"


class ConfigError(Exception):
    """A configuration could not be used; ``problems`` says why and where."""

    def __init__(self, problems: Iterable[Problem]) -> None:
        self.problems: list[Problem] = list(problems)
        super().__init__(self.problems)

    @classmethod
    def at(cls, file: str, line: int, message: str) -> ConfigError:
        """An error with a single problem."""
        return cls([Problem(file, line, message)])

    def __str__(self) -> str:
        return "\n".join(str(p) for p in self.problems)


class Problems:
    """Collects problems while a file is checked, then raises them together."""

    def __init__(self) -> None:
        self.problems: list[Problem] = []

    def add(self, file: str, line: int, message: str) -> None:
        self.problems.append(Problem(file, line, message))

    @contextmanager
    def collect(self) -> Iterator[None]:
        """Record the problems of a ConfigError raised inside the block."""
        try:
            yield
        except ConfigError as error:
            self.problems.extend(error.problems)

    def __bool__(self) -> bool:
        return bool(self.problems)

    def raise_if_any(self) -> None:
        if self.problems:
            raise ConfigError(self.problems)


def did_you_mean(word: str, candidates: Iterable[str]) -> str:
    """A ``" (did you mean 'x'?)"`` suffix for a message, or ``""``."""
    matches = difflib.get_close_matches(word, sorted(set(candidates)), n=1)
    return f" (did you mean '{matches[0]}'?)" if matches else ""

"""Problems found in a model file, and the error that carries them."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass


@dataclass(frozen=True)
class Problem:
    """One thing wrong with a model, and where it is."""

    file: str
    line: int | None
    message: str

    def __str__(self) -> str:
        where = self.file if self.line is None else f"{self.file}:{self.line}"
        return f"{where}: {self.message}"


class ModelError(Exception):
    """A model could not be loaded; ``problems`` lists every reason found.

    ``file`` and ``line`` are those of the first problem, and ``str()`` gives
    one ``file:line: message`` line per problem.
    """

    def __init__(self, problems: Iterable[Problem]) -> None:
        self.problems: list[Problem] = list(problems)
        if not self.problems:
            raise ValueError("ModelError needs at least one problem")
        self.file: str = self.problems[0].file
        self.line: int | None = self.problems[0].line
        super().__init__("\n".join(str(p) for p in self.problems))

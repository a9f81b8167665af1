"""Generator files: a scan written as JSON or YAML, for ``malcolm points``.

Reading a file is kept apart from `malcolm.scan.scan_points`, which takes
only data: a caller's argument never names a file on the server. YAML is read
by `malcolm.yamlio`, so a problem in a YAML file is reported at its line,
both a syntax error and a bad value (``generators[0].size``).
"""

from __future__ import annotations

import json
import os
import re
from typing import Any

from malcolm import yamlio

from .errors import GeneratorError
from .load import scan_points
from .points import ScanPoints

__all__ = ["GeneratorFileError", "points_from_file", "read_generator_file"]


class GeneratorFileError(GeneratorError):
    """A generator file is unreadable or holds a bad scan.

    ``str()`` is ``file:line: message`` (``file: message`` with no line).
    """

    def __init__(self, file: str, line: int | None, path: str, reason: str) -> None:
        super().__init__(path, reason)
        self.file = file
        self.line = line
        where = file if line is None else f"{file}:{line}"
        self.args = (f"{where}: {super().__str__()}",)

    def __str__(self) -> str:
        return str(self.args[0])


def read_generator_file(path: str | os.PathLike[str]) -> Any:
    """The data in a JSON (``.json``) or YAML (any other name) file.

    YAML mappings and sequences come back as `malcolm.yamlio.LineDict` and
    `~malcolm.yamlio.LineList`, which know their lines.

    Raises:
        GeneratorFileError: if the file cannot be read or parsed.
    """
    file = str(path)
    try:
        text = yamlio.read_text(path)
        if file.lower().endswith(".json"):
            return _json(text, file)
        data, problems = yamlio.load(file, text)
    except yamlio.YamlError as e:
        raise _located(e.problem) from None
    if problems:
        raise _located(problems[0])
    return data


def _json(text: str, file: str) -> Any:
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise GeneratorFileError(file, e.lineno, "", f"invalid JSON: {e.msg}") from None
    except RecursionError:
        raise GeneratorFileError(file, None, "", yamlio.NESTED_TOO_DEEPLY) from None


def _located(problem: yamlio.YamlProblem) -> GeneratorFileError:
    return GeneratorFileError(problem.file, problem.line, "", problem.message)


def points_from_file(path: str | os.PathLike[str]) -> ScanPoints:
    """Every point of the scan in a generator file.

    Raises:
        GeneratorFileError: naming the file, and the line of the bad item
            where the file is YAML.
    """
    data = read_generator_file(path)
    try:
        return scan_points(data)
    except GeneratorError as e:
        line = line_of_path(data, e.path)
        raise GeneratorFileError(str(path), line, e.path, e.reason) from None


_STEP = re.compile(r"\[(\d+)\]|\.?([^.\[\]]+)")


def line_of_path(data: Any, path: str) -> int | None:
    """The line of the item at ``path`` (``generators[1].size``) in data read
    from YAML, or of its nearest parent; None if nothing has a line."""
    line = getattr(data, "line", None)
    here = data
    for match in _STEP.finditer(path):
        index, key = match.groups()
        if index is not None and isinstance(here, yamlio.LineList):
            position = int(index)
            if position >= len(here):
                break
            line, here = here.line_of(position), here[position]
        elif key is not None and isinstance(here, yamlio.LineDict) and key in here:
            line, here = here.line_of(key), here[key]
        else:
            break
    return line

"""Replace ``{name}`` references with parameter values.

Rules, applied to every string in a value (inside dicts and lists, and in
dict keys):

- ``{name}`` (letters, digits, ``_``) is replaced by the value of ``name``;
- a string that is exactly ``{name}`` becomes the value itself, keeping its
  type (an Int parameter stays an int); in keys the result is always text;
- ``{{`` and ``}}`` stand for literal ``{`` and ``}``; any other brace is
  kept as written;
- an unknown name, or a parameter without a value used inside a longer
  string, is an error naming the file and line.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Callable, Mapping
from typing import Any

from .errors import Problems, did_you_mean
from .yamlsections import Section, ValuePath

_TOKEN = re.compile(r"\{\{|\}\}|\{([A-Za-z_][A-Za-z0-9_]*)\}")
_WHOLE = re.compile(r"\{([A-Za-z_][A-Za-z0-9_]*)\}")

LineOf = Callable[[ValuePath], int]


def references(value: Any) -> set[str]:
    """The names referenced anywhere in ``value``."""
    found: set[str] = set()
    if isinstance(value, str):
        found.update(m[1] for m in _TOKEN.finditer(value) if m[1])
    elif isinstance(value, dict):
        for key, item in value.items():
            found |= references(key) | references(item)
    elif isinstance(value, list):
        for item in value:
            found |= references(item)
    return found


def substitute(
    value: Any,
    names: Mapping[str, Any],
    *,
    file: str,
    line: int | LineOf = 1,
) -> Any:
    """Substitute ``names`` into ``value``; raise ConfigError if any fail.

    ``line`` is either the line of the value or a function from a path below
    ``value`` (``("value", 0, "x")``) to a line.
    """
    line_of: LineOf = line if callable(line) else (lambda path, n=line: n)
    problems = Problems()
    result, _ = _Substituter(names, file, line_of, problems).value(value, ())
    problems.raise_if_any()
    return result


def substitute_section(section: Section, names: Mapping[str, Any]) -> Section:
    """A copy of ``section`` with ``names`` substituted into its parameters.

    Line information follows renamed keys.
    """
    problems = Problems()
    sub = _Substituter(names, section.file, section.line_of, problems)
    params: dict[str, Any] = {}
    param_lines: dict[str, int] = {}
    value_lines: dict[ValuePath, int] = {}
    for key, item in section.params.items():
        new_key = sub.key(key, (key,))
        if new_key in params:
            problems.add(
                section.file,
                section.line_of((key,)),
                f"parameter '{new_key}' given twice after substitution",
            )
            continue
        params[new_key], moved = sub.value(item, (key,))
        for new, old in moved.items():
            value_lines[(new_key, *new)] = section.line_of((key, *old))
        if key in section.param_lines:
            param_lines[new_key] = section.param_lines[key]
    problems.raise_if_any()
    return dataclasses.replace(
        section, params=params, param_lines=param_lines, value_lines=value_lines
    )


class _Substituter:
    def __init__(
        self, names: Mapping[str, Any], file: str, line_of: LineOf, problems: Problems
    ) -> None:
        self.names = names
        self.file = file
        self.line_of = line_of
        self.problems = problems

    def value(self, value: Any, path: ValuePath) -> tuple[Any, dict[ValuePath, Any]]:
        """Substitute into ``value`` at ``path``.

        Returns the new value and a map from each new sub-path (relative to
        ``value``) to the old one, so line numbers can follow renamed keys.
        """
        moved: dict[ValuePath, Any] = {(): ()}
        if isinstance(value, str):
            return self.string(value, path, whole=True), moved
        if isinstance(value, list):
            items = []
            for i, item in enumerate(value):
                new, sub_moved = self.value(item, (*path, i))
                items.append(new)
                moved.update({(i, *n): (i, *o) for n, o in sub_moved.items()})
            return items, moved
        if isinstance(value, dict):
            result: dict[Any, Any] = {}
            for key, item in value.items():
                new_key = self.key(key, (*path, key))
                if new_key in result:
                    self.problems.add(
                        self.file,
                        self.line_of((*path, key)),
                        f"key '{new_key}' appears twice after substitution",
                    )
                    continue
                result[new_key], sub_moved = self.value(item, (*path, key))
                moved.update({(new_key, *n): (key, *o) for n, o in sub_moved.items()})
            return result, moved
        return value, moved

    def key(self, key: Any, path: ValuePath) -> Any:
        return self.string(key, path, whole=False) if isinstance(key, str) else key

    def string(self, text: str, path: ValuePath, *, whole: bool) -> Any:
        if "{" not in text and "}" not in text:
            return text
        if whole and (match := _WHOLE.fullmatch(text)):
            name = match[1]
            if self._known(name, path):
                return self.names[name]
            return text
        return _TOKEN.sub(lambda m: self._piece(m, path), text)

    def _piece(self, match: re.Match[str], path: ValuePath) -> str:
        name = match[1]
        if name is None:
            return match[0][0]
        if not self._known(name, path):
            return match[0]
        value = self.names[name]
        if value is None:
            self.problems.add(
                self.file,
                self.line_of(path),
                f"parameter '{name}' has no value (not given, no default)",
            )
            return match[0]
        return str(value)

    def _known(self, name: str, path: ValuePath) -> bool:
        if name in self.names:
            return True
        where = ".".join(str(p) for p in path)
        self.problems.add(
            self.file,
            self.line_of(path),
            f"unknown parameter '{{{name}}}'"
            + (f" in '{where}'" if where else "")
            + did_you_mean(name, self.names),
        )
        return False

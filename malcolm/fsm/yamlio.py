"""Read YAML keeping the line number of every mapping, sequence and key."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from .errors import Problem


class LineDict(dict):
    """A YAML mapping; ``line`` is where it starts, ``key_lines`` per key."""

    line: int | None = None

    def __init__(self) -> None:
        super().__init__()
        self.key_lines: dict[Any, int] = {}

    def line_of(self, key: Any) -> int | None:
        return self.key_lines.get(key, self.line)


class LineList(list):
    """A YAML sequence; ``line`` is where it starts, ``item_lines`` per item."""

    line: int | None = None

    def __init__(self) -> None:
        super().__init__()
        self.item_lines: list[int] = []

    def line_of(self, index: int) -> int | None:
        if 0 <= index < len(self.item_lines):
            return self.item_lines[index]
        return self.line


class _LineLoader(yaml.SafeLoader):
    def __init__(self, stream: str) -> None:
        super().__init__(stream)
        self.duplicates: list[tuple[int, str]] = []


def _line(node: yaml.Node) -> int:
    return node.start_mark.line + 1


def _construct_map(loader: _LineLoader, node: yaml.MappingNode) -> LineDict:
    data = LineDict()
    data.line = _line(node)
    loader.flatten_mapping(node)
    for key_node, value_node in node.value:
        key = loader.construct_object(key_node, deep=True)
        if isinstance(key, list | dict):
            key = str(key)
        if key in data:
            loader.duplicates.append((_line(key_node), str(key)))
        data[key] = loader.construct_object(value_node, deep=True)
        data.key_lines[key] = _line(key_node)
    return data


def _construct_seq(loader: _LineLoader, node: yaml.SequenceNode) -> LineList:
    data = LineList()
    data.line = _line(node)
    for child in node.value:
        data.append(loader.construct_object(child, deep=True))
        data.item_lines.append(_line(child))
    return data


_LineLoader.add_constructor("tag:yaml.org,2002:map", _construct_map)
_LineLoader.add_constructor("tag:yaml.org,2002:seq", _construct_seq)


def read_yaml(path: Path) -> tuple[Any, list[Problem]]:
    """Parse ``path``; returns the data (None on failure) and the problems."""
    file = str(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as e:
        return None, [Problem(file, None, f"cannot read model file: {e.strerror}")]
    except UnicodeDecodeError as e:
        return None, [Problem(file, None, f"not UTF-8 text: {e.reason}")]
    try:
        loader = _LineLoader(text)
    except yaml.YAMLError as e:  # e.g. a character YAML does not allow
        return None, [Problem(file, None, f"bad YAML: {e}")]
    try:
        data = loader.get_single_data()
    except yaml.MarkedYAMLError as e:
        mark = e.problem_mark or e.context_mark
        line = None if mark is None else mark.line + 1
        message = " ".join(m for m in (e.context, e.problem) if m)
        return None, [Problem(file, line, f"bad YAML: {message}")]
    except yaml.YAMLError as e:
        return None, [Problem(file, None, f"bad YAML: {e}")]
    except RecursionError:
        return None, [Problem(file, 1, "the document is nested too deeply")]
    finally:
        loader.dispose()
    problems = [
        Problem(file, line, f"duplicate key {key!r} (the same name twice in a file)")
        for line, key in loader.duplicates
    ]
    return data, problems

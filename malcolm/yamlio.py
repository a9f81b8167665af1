"""The one YAML reader: every loader of malcolm reads YAML through it.

Models (``malcolm.fsm``), definitions, process files and designs
(``malcolm.config``) and scan files (``malcolm.scan``) all read a document
in the same three steps, so every file gets the same rules and every problem
the same ``file:line`` form:

1. :func:`read_text`: the file's UTF-8 text;
2. :func:`compose`: the YAML node tree (aliases are refused, and a caller
   may give a ``fallback`` that rewrites text which does not parse);
3. :func:`construct`: plain Python values, in which every mapping is a
   :class:`LineDict` and every sequence a :class:`LineList` that know the
   line of each key, value and item. A duplicate key, a key that is not a
   plain value, a bad scalar or a tag other than YAML's own is a problem;
   the first value of a duplicated key is kept.

:func:`load` does all three. A problem that stops the document being read
raises :class:`YamlError`; the others are returned with the data.
Scalars follow YAML 1.1 as PyYAML reads them (``Yes`` is true).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml
from yaml.nodes import MappingNode, Node, ScalarNode, SequenceNode

__all__ = [
    "LineDict",
    "LineList",
    "YamlError",
    "YamlProblem",
    "compose",
    "construct",
    "load",
    "plain",
    "read_text",
    "value_lines",
]

MAP_TAG = "tag:yaml.org,2002:map"
SEQ_TAG = "tag:yaml.org,2002:seq"
NULL_TAG = "tag:yaml.org,2002:null"
STR_TAG = "tag:yaml.org,2002:str"

NESTED_TOO_DEEPLY = "the document is nested too deeply"


@dataclass(frozen=True)
class YamlProblem:
    """One thing wrong with a document; ``line`` is 1-based, or None."""

    file: str
    line: int | None
    message: str

    def __str__(self) -> str:
        where = self.file if self.line is None else f"{self.file}:{self.line}"
        return f"{where}: {self.message}"


class YamlError(Exception):
    """A document could not be read at all; ``problem`` says where and why."""

    def __init__(self, problem: YamlProblem) -> None:
        self.problem = problem
        super().__init__(str(problem))


class LineDict(dict):
    """A YAML mapping that knows its lines.

    ``line`` is where the mapping starts, ``key_lines[key]`` the line of a
    key and ``value_lines[key]`` the line of its value (a nested block starts
    on the line after its key).
    """

    line: int | None = None

    def __init__(self) -> None:
        super().__init__()
        self.key_lines: dict[Any, int] = {}
        self.value_lines: dict[Any, int] = {}

    def line_of(self, key: Any) -> int | None:
        """The line of ``key``, or of the mapping if it has no such key."""
        return self.key_lines.get(key, self.line)


class LineList(list):
    """A YAML sequence; ``line`` is where it starts, ``item_lines`` per item."""

    line: int | None = None

    def __init__(self) -> None:
        super().__init__()
        self.item_lines: list[int] = []

    def line_of(self, index: int) -> int | None:
        """The line of item ``index``, or of the sequence if there is none."""
        if 0 <= index < len(self.item_lines):
            return self.item_lines[index]
        return self.line


def line_of(node: Node) -> int:
    """The 1-based line where ``node`` starts."""
    return node.start_mark.line + 1


def read_text(path: str | os.PathLike[str]) -> str:
    """The UTF-8 text of ``path``; YamlError if it cannot be read."""
    file = str(path)
    try:
        data = Path(path).read_bytes()
    except OSError as e:
        reason = e.strerror or str(e)
        raise YamlError(
            YamlProblem(file, None, f"cannot read file: {reason}")
        ) from None
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as e:
        line = data.count(b"\n", 0, e.start) + 1
        raise YamlError(
            YamlProblem(file, line, f"file is not UTF-8: {e.reason}")
        ) from None


class _Composer(yaml.SafeLoader):
    """A SafeLoader that refuses aliases (``*name``)."""

    def compose_node(self, parent: Node | None, index: Any) -> Node | None:
        if self.check_event(yaml.AliasEvent):
            mark = self.peek_event().start_mark
            raise yaml.composer.ComposerError(
                None, None, "aliases (*name) are not supported", mark
            )
        return super().compose_node(parent, index)


def _compose_once(text: str) -> Node | None:
    loader = _Composer(text)
    try:
        return loader.get_single_node()
    finally:
        loader.dispose()


# libyaml's composer, when PyYAML was built with it: about ten times faster
# than the pure-Python one (a process file of a thousand blocks, every model
# file). It is used only for documents it reads without a problem and that
# use no alias; anything else is read again by the pure-Python composer
# above, so every problem is reported by that one, in its words.
_CLoader: Any = getattr(yaml, "CSafeLoader", None)


class _NotFast(Exception):
    """The document needs the pure-Python composer."""


def _shares_a_node(root: Node) -> bool:
    """Whether a node appears twice in the tree (what an alias composes to)."""
    seen: set[int] = set()
    todo = [root]
    while todo:
        node = todo.pop()
        if id(node) in seen:
            return True
        seen.add(id(node))
        if isinstance(node, MappingNode):
            for key, value in node.value:
                todo.append(key)
                todo.append(value)
        elif isinstance(node, SequenceNode):
            todo.extend(node.value)
    return False


def _compose_fast(text: str) -> Node | None:
    """``text``'s node tree by libyaml; _NotFast if it has any problem."""
    try:
        loader = _CLoader(text)
        try:
            node = loader.get_single_node()
        finally:
            loader.dispose()
    except Exception:  # its problems are the pure-Python composer's to tell
        raise _NotFast() from None
    if node is not None and _shares_a_node(node):
        raise _NotFast()
    return node


def compose(
    text: str,
    file: str = "<string>",
    fallback: Callable[[str], str] | None = None,
) -> tuple[Node | None, str]:
    """The node tree of ``text`` (None if empty) and the text it was read from.

    If ``text`` does not parse and ``fallback`` is given, ``fallback(text)``
    is parsed instead (it must keep every line where it was); the problem
    reported is then that of the rewritten text. Raises YamlError.
    """
    if _CLoader is not None:
        try:
            return _compose_fast(text), text
        except _NotFast:
            pass
        if fallback is not None:
            rewritten = fallback(text)
            try:
                return _compose_fast(rewritten), rewritten
            except _NotFast:
                pass
    if fallback is not None:
        try:
            return _compose_once(text), text
        except (yaml.YAMLError, RecursionError):
            text = fallback(text)
    try:
        return _compose_once(text), text
    except yaml.MarkedYAMLError as e:
        mark = e.problem_mark or e.context_mark
        line = mark.line + 1 if mark else None
        message = " ".join(m for m in (e.context, e.problem) if m)
        problem = YamlProblem(file, line, f"YAML error: {message}")
    except yaml.reader.ReaderError as e:  # a character YAML does not allow
        line = text.count("\n", 0, e.position) + 1
        problem = YamlProblem(file, line, f"YAML error: {e.reason}")
    except yaml.YAMLError as e:
        problem = YamlProblem(file, None, f"YAML error: {e}")
    except RecursionError:
        problem = YamlProblem(file, 1, NESTED_TOO_DEEPLY)
    raise YamlError(problem)


class _Constructor:
    """Turns nodes into values, LineDicts and LineLists, noting problems."""

    def __init__(self, file: str) -> None:
        self.file = file
        self.problems: list[YamlProblem] = []
        self.scalars = yaml.SafeLoader("")

    def add(self, node: Node, message: str) -> None:
        self.problems.append(YamlProblem(self.file, line_of(node), message))

    def value(self, node: Node) -> Any:
        if isinstance(node, ScalarNode):
            try:
                return self.scalars.construct_object(node, deep=True)
            except Exception as e:  # a bad scalar raises many kinds
                self.add(node, f"bad value: {getattr(e, 'problem', None) or e}")
                return None
        if isinstance(node, SequenceNode) and node.tag == SEQ_TAG:
            items = LineList()
            items.line = line_of(node)
            for child in node.value:
                items.append(self.value(child))
                items.item_lines.append(line_of(child))
            return items
        if isinstance(node, MappingNode) and node.tag == MAP_TAG:
            return self.mapping(node)
        self.add(node, f"unsupported YAML tag {node.tag}")
        return None

    def mapping(self, node: MappingNode) -> LineDict:
        data = LineDict()
        data.line = line_of(node)
        for key_node, value_node in node.value:
            key = self.value(key_node)
            try:
                duplicate = key in data
            except TypeError:
                self.add(key_node, "mapping key must be a plain value")
                continue
            if duplicate:
                self.add(
                    key_node,
                    f"duplicate key {_say(key)} "
                    f"(first given at line {data.key_lines[key]})",
                )
                continue
            data[key] = self.value(value_node)
            data.key_lines[key] = line_of(key_node)
            data.value_lines[key] = line_of(value_node)
        return data


def _say(key: Any) -> str:
    return f"'{key}'" if isinstance(key, str) else repr(key)


def construct(
    node: Node | None, file: str = "<string>"
) -> tuple[Any, list[YamlProblem]]:
    """The Python value of ``node`` and the problems found on the way."""
    if node is None:
        return None, []
    builder = _Constructor(file)
    try:
        return builder.value(node), builder.problems
    except RecursionError:
        raise YamlError(YamlProblem(file, 1, NESTED_TOO_DEEPLY)) from None


def load(
    path: str | os.PathLike[str], text: str | None = None
) -> tuple[Any, list[YamlProblem]]:
    """Read, compose and construct the document at ``path`` (or ``text``,
    named ``path`` in problems). Raises YamlError if it cannot be read."""
    file = str(path)
    if text is None:
        text = read_text(path)
    node, _ = compose(text, file)
    return construct(node, file)


ValuePath = tuple[Any, ...]


def plain(value: Any) -> Any:
    """``value`` with every LineDict a dict and every LineList a list."""
    if isinstance(value, dict):
        return {k: plain(v) for k, v in value.items()}
    if isinstance(value, list):
        return [plain(v) for v in value]
    return value


def value_lines(value: Any, path: ValuePath = ()) -> Iterator[tuple[ValuePath, int]]:
    """``(path, line)`` of every value nested in ``value`` (not ``value``
    itself): ``("a", 0)`` for ``value["a"][0]``."""
    if isinstance(value, LineDict):
        for key, item in value.items():
            yield (*path, key), value.value_lines[key]
            yield from value_lines(item, (*path, key))
    elif isinstance(value, LineList):
        for index, item in enumerate(value):
            yield (*path, index), value.item_lines[index]
            yield from value_lines(item, (*path, index))

"""Parse a definition document into an ordered list of sections.

A definition is a YAML mapping whose keys name section types (``ca.Double``,
``parts.PalettePart``...) and whose values are the section's parameters. Unlike
a stock YAML load, the same key may appear many times (a saved design has one
``parts.PalettePart`` per block), so the document is composed into nodes and
read pair by pair, which also tells every section and value its line.

The language writes parameter references unquoted, as in ``pv:
{prefix}:Exposure`` or ``prefix: {pvprefix}``. In YAML the first is a syntax
error and the second a flow mapping ``{pvprefix: null}``. Both are read as
the text ``{name}...``:

- a flow mapping written exactly ``{name}`` (one key, no value) becomes the
  string ``"{name}"``, wherever it appears;
- if the document does not parse, every value that starts with ``{name}``
  (after ``key:`` or ``-``) is quoted, line by line, and the document is
  parsed again. Line numbers are unchanged by this.

The document is read by :mod:`malcolm.yamlio`, the reader every loader
uses: scalars follow YAML 1.1 as PyYAML reads them (``visible: Yes`` is
True); anchors and aliases are not part of the language.
"""

from __future__ import annotations

import os
import re
from collections.abc import Collection
from dataclasses import dataclass, field
from typing import Any

from yaml.nodes import MappingNode, Node, ScalarNode, SequenceNode

from malcolm import yamlio

from .errors import ConfigError, Problems

ValuePath = tuple[Any, ...]

_IDENT = r"[A-Za-z_][A-Za-z0-9_]*"
_COMPONENT = r"[A-Za-z0-9_][A-Za-z0-9_-]*"
#: ``namespace.Name.Dotted`` with an optional ``:attribute`` (import paths).
KIND_RE = re.compile(rf"{_IDENT}(?:\.{_COMPONENT})*(?::{_IDENT}(?:\.{_IDENT})*)?")


@dataclass(frozen=True)
class Section:
    """One top-level entry of a definition, such as ``ca.Double: {...}``."""

    kind: str  #: the whole key, e.g. "block.ADCore.PositionPlugin"
    namespace: str  #: text before the first dot, e.g. "block"
    name: str  #: text after the first dot, e.g. "ADCore.PositionPlugin"
    params: dict[str, Any]
    file: str
    line: int  #: line of the section's key
    param_lines: dict[str, int] = field(default_factory=dict)
    #: line of every value, keyed by its path below ``params``:
    #: ``("value", 0, "Phase1Time")`` for ``params["value"][0]["Phase1Time"]``
    value_lines: dict[ValuePath, int] = field(default_factory=dict)

    def line_of(self, path: ValuePath = ()) -> int:
        """The line of the value at ``path``, or of its nearest parent."""
        path = tuple(path)
        while path:
            if path in self.value_lines:
                return self.value_lines[path]
            if len(path) == 1 and path[0] in self.param_lines:
                return self.param_lines[path[0]]
            path = path[:-1]
        return self.line


def split_kind(kind: str) -> tuple[str, str]:
    """``"block.ADCore.PositionPlugin"`` -> ``("block", "ADCore.PositionPlugin")``."""
    namespace, _, name = kind.partition(".")
    return namespace, name


def load_sections(
    path: str | os.PathLike[str], *, value_kinds: Collection[str] = ()
) -> list[Section]:
    """Read a file and parse it with :func:`parse_sections`."""
    try:
        text = yamlio.read_text(path)
    except yamlio.YamlError as error:
        raise _config_error(error) from None
    return parse_sections(text, str(path), value_kinds=value_kinds)


def parse_sections(
    text: str, file: str = "<string>", *, value_kinds: Collection[str] = ()
) -> list[Section]:
    """Parse a document into its sections, in order, repeated keys kept.

    Each section's body must be a mapping of parameters, or empty (no
    parameters), except for the kinds in ``value_kinds``, whose body may be
    any value and is stored as ``params["value"]``.
    Raises :class:`ConfigError` listing every problem found.
    """
    try:
        root, composed = yamlio.compose(text, file, fallback=quote_references)
    except yamlio.YamlError as error:
        raise _config_error(error) from None
    if root is None:
        return []
    problems = Problems()
    if not isinstance(root, MappingNode) or root.tag != yamlio.MAP_TAG:
        problems.add(file, _line(root), "a definition must be a mapping of sections")
        problems.raise_if_any()
    _unbrace(root, composed)
    reader = _Reader(file, problems)
    sections = [
        section
        for key, body in root.value
        if (section := reader.section(key, body, value_kinds)) is not None
    ]
    problems.problems.sort(key=lambda p: p.line)
    problems.raise_if_any()
    return sections


def _config_error(error: yamlio.YamlError) -> ConfigError:
    problem = error.problem
    return ConfigError.at(problem.file, problem.line or 1, problem.message)


_line = yamlio.line_of


# ``key: {name}...`` or ``- {name}...``: the value is group "value".
_REF_LINE = re.compile(
    rf"""(?P<lead>[ ]*(?:-[ ]+)*
        (?:(?:[^\s#'"{{}}\[\],&*!|>%@`?-][^#]*?|"[^"]*"|'[^']*')[ ]*:[ ]+)?)
        (?P<value>\{{{_IDENT}\}}.*?)
        (?P<trail>[ \t]+\#.*)?[ \t]*""",
    re.VERBOSE,
)
# A line whose value is a block scalar (``key: |`` or ``- >-``).
_BLOCK_SCALAR = re.compile(
    r"""(?P<dashes>[ ]*(?:-[ ]+)*)(?P<key>[^#]*?:[ ]+)?
        [|>][-+1-9]{0,2}[ \t]*(?:\#.*)?""",
    re.VERBOSE,
)


def quote_references(text: str) -> str:
    """Single-quote every value that starts with an unquoted ``{name}``.

    ``pv: {prefix}:Exposure  # c`` becomes ``pv: '{prefix}:Exposure'  # c``.
    Block scalars are left alone; no line is added or removed.
    """
    out: list[str] = []
    block_indent: int | None = None
    for line in text.split("\n"):
        body = line.rstrip("\r")
        indent = len(body) - len(body.lstrip(" "))
        if block_indent is not None:
            if not body.strip() or indent > block_indent:
                out.append(line)
                continue
            block_indent = None
        if match := _BLOCK_SCALAR.fullmatch(body):
            dashes = match["dashes"]
            block_indent = len(dashes) if match["key"] else dashes.rfind("-")
            out.append(line)
        elif match := _REF_LINE.fullmatch(body):
            value = "'" + match["value"].replace("'", "''") + "'"
            out.append(match["lead"] + value + (match["trail"] or ""))
        else:
            out.append(line)
    return "\n".join(out)


_BRACED = re.compile(rf"\{{\s*{_IDENT}\s*\}}")


def _unbrace(node: Node, text: str) -> None:
    """Turn flow mappings written ``{name}`` into the scalar text ``{name}``."""
    if isinstance(node, SequenceNode):
        node.value = [_unbraced(item, text) for item in node.value]
    elif isinstance(node, MappingNode):
        node.value = [(_unbraced(k, text), _unbraced(v, text)) for k, v in node.value]


def _unbraced(node: Node, text: str) -> Node:
    if (
        isinstance(node, MappingNode)
        and node.flow_style
        and len(node.value) == 1
        and _BRACED.fullmatch(text[node.start_mark.index : node.end_mark.index])
    ):
        key, value = node.value[0]
        if isinstance(key, ScalarNode) and value.tag == yamlio.NULL_TAG:
            return ScalarNode(
                yamlio.STR_TAG,
                "{" + key.value + "}",
                node.start_mark,
                node.end_mark,
                "'",
            )
    _unbrace(node, text)
    return node


class _Reader:
    """Turns the composed top-level pairs into sections of plain values."""

    def __init__(self, file: str, problems: Problems) -> None:
        self.file = file
        self.problems = problems

    def section(
        self, key: Node, body: Node, value_kinds: Collection[str]
    ) -> Section | None:
        if not isinstance(key, ScalarNode) or not isinstance(key.value, str):
            self.problems.add(self.file, _line(key), "section name must be text")
            return None
        kind = key.value
        if not KIND_RE.fullmatch(kind):
            self.problems.add(
                self.file,
                _line(key),
                f"invalid section name '{kind}' (expected namespace.Name)",
            )
            return None
        namespace, name = split_kind(kind)
        params: dict[str, Any] = {}
        param_lines: dict[str, int] = {}
        value_lines: dict[ValuePath, int] = {}
        if isinstance(body, MappingNode) and body.tag == yamlio.MAP_TAG:
            for pkey, pvalue in body.value:
                if not isinstance(pkey, ScalarNode):
                    self.problems.add(
                        self.file, _line(pkey), "parameter name must be text"
                    )
                    continue
                pname = pkey.value
                if pname in params:
                    self.problems.add(
                        self.file,
                        _line(pkey),
                        f"duplicate parameter '{pname}' in {kind} "
                        f"(first given at line {param_lines[pname]})",
                    )
                    continue
                param_lines[pname] = _line(pkey)
                params[pname] = self.value(pvalue, pname, value_lines)
        elif kind in value_kinds:
            params["value"] = self.value(body, "value", value_lines)
            param_lines["value"] = _line(body)
        elif not (isinstance(body, ScalarNode) and body.tag == yamlio.NULL_TAG):
            self.problems.add(
                self.file,
                _line(body),
                f"body of {kind} must be a mapping of parameters",
            )
        return Section(
            kind,
            namespace,
            name,
            params,
            self.file,
            _line(key),
            param_lines,
            value_lines,
        )

    def value(self, node: Node, name: str, lines: dict[ValuePath, int]) -> Any:
        """The plain value of parameter ``name``; its lines go into ``lines``."""
        value, problems = yamlio.construct(node, self.file)
        for problem in problems:
            self.problems.add(problem.file, problem.line or 1, problem.message)
        lines[(name,)] = _line(node)
        lines.update(yamlio.value_lines(value, (name,)))
        return yamlio.plain(value)

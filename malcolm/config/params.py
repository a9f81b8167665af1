"""Initialisation parameters: ``init.*`` sections and checking given values.

``init.String``, ``init.Int``, ``init.Float`` and ``init.Boolean`` declare a
parameter of that type; ``init.<Dotted.Name>`` (such as
``init.ADCore.DetectorDriver``) declares a reference to another block, whose
value is that block's mri, any non-empty text. Each section takes ``name``
(required), ``description``, ``required`` (default false) and ``default``.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from .errors import Problems, did_you_mean
from .yamlsections import Section

#: The scalar types an ``init.*`` section may declare.
SCALAR_TYPES = ("String", "Int", "Float", "Boolean")
#: Names every block has without declaring them (see the substitution rules).
RESERVED_NAMES = frozenset({"mri"})
_NAME_RE = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_KEYS = ("name", "description", "required", "default")


@dataclass(frozen=True)
class InitParam:
    """A parameter a definition takes when a block is made from it."""

    name: str
    type: str  #: "String", "Int", "Float", "Boolean" or a block type
    description: str = ""
    required: bool = False
    default: Any = None
    file: str = "<unknown>"
    line: int = 1

    @property
    def is_block_reference(self) -> bool:
        """True for ``init.ADCore.DetectorDriver``-style parameters."""
        return self.type not in SCALAR_TYPES


def check_value(type_name: str, value: Any) -> tuple[bool, Any]:
    """Check ``value`` against a parameter type: ``(ok, converted value)``.

    Ints are accepted for Float (and become floats); a bool is not an Int or
    a Float; a block reference is any non-empty text.
    """
    if type_name == "String":
        return isinstance(value, str), value
    if type_name == "Int":
        return isinstance(value, int) and not isinstance(value, bool), value
    if type_name == "Float":
        if isinstance(value, bool) or not isinstance(value, int | float):
            return False, value
        try:
            return True, float(value)
        except OverflowError:  # an int too big for a float
            return False, value
    if type_name == "Boolean":
        return isinstance(value, bool), value
    return isinstance(value, str) and value.strip() != "", value


def describe_type(type_name: str) -> str:
    """How a type is named in messages: "an Int", "a String"..."""
    if type_name == "Int":
        return "an Int"
    if type_name in SCALAR_TYPES:
        return f"a {type_name}"
    return f"an mri of a {type_name} block (text)"


def param_from_section(section: Section) -> InitParam:
    """Read one ``init.*`` section, raising ConfigError for every mistake."""
    problems = Problems()
    file, params = section.file, section.params
    type_name = section.name
    if type_name not in SCALAR_TYPES and "." not in type_name:
        problems.add(
            file,
            section.line,
            f"unknown parameter type '{section.kind}'"
            + did_you_mean(section.kind, (f"init.{t}" for t in SCALAR_TYPES))
            + " (block references are written init.Module.Block)",
        )
    for key in params:
        if key not in _KEYS:
            problems.add(
                file,
                section.line_of((key,)),
                f"unknown key '{key}' in {section.kind}" + did_you_mean(key, _KEYS),
            )
    name = params.get("name")
    if name is None:
        problems.add(file, section.line, f"{section.kind} needs a 'name'")
    elif not isinstance(name, str) or not _NAME_RE.fullmatch(name):
        problems.add(
            file,
            section.line_of(("name",)),
            f"parameter name {name!r} must be letters, digits and _",
        )
    elif name in RESERVED_NAMES:
        problems.add(
            file, section.line_of(("name",)), f"parameter name '{name}' is reserved"
        )
    description = params.get("description", "")
    if not isinstance(description, str):
        problems.add(
            file, section.line_of(("description",)), "description must be text"
        )
    required = params.get("required", False)
    if not isinstance(required, bool):
        problems.add(
            file, section.line_of(("required",)), "required must be true or false"
        )
    default = params.get("default")
    if default is not None:
        ok, default = check_value(type_name, default)
        if not ok:
            problems.add(
                file,
                section.line_of(("default",)),
                f"default {default!r} is not {describe_type(type_name)}",
            )
    problems.raise_if_any()
    return InitParam(
        name, type_name, description, required, default, file, section.line
    )


def resolve_params(
    declared: Sequence[InitParam],
    given: Mapping[str, Any],
    file: str,
    *,
    line: int | None = None,
    given_lines: Mapping[str, int] | None = None,
    context: str = "",
) -> dict[str, Any]:
    """Check given values against declared parameters; apply defaults.

    ``file``/``line`` locate the place that gives the values (a ``block.X``
    section, a process file entry); ``given_lines`` the line of each value.
    Without ``line``, a missing parameter is reported where it is declared.
    ``context`` (e.g. the definition's name) starts every message.
    A value of None counts as not given. Parameters that are neither given
    nor defaulted resolve to None. Raises ConfigError listing every missing
    required parameter, unknown parameter and value of the wrong type.
    """
    lines = given_lines or {}
    problems = Problems()
    prefix = f"{context}: " if context else ""

    def where(key: str | None, param: InitParam | None = None) -> tuple[str, int]:
        if key is not None and key in lines:
            return file, lines[key]
        if line is not None:
            return file, line
        return (param.file, param.line) if param else (file, 1)

    by_name = {p.name: p for p in declared}
    for key in given:
        if key not in by_name:
            known = ", ".join(by_name) or "none"
            problems.add(
                *where(key),
                f"{prefix}unknown parameter '{key}'"
                + did_you_mean(str(key), by_name)
                + f" (parameters: {known})",
            )
    resolved: dict[str, Any] = {}
    for param in declared:
        value = given.get(param.name)
        if value is None:
            if param.required:
                problems.add(
                    *where(None, param),
                    f"{prefix}missing required parameter '{param.name}'"
                    + (f" ({param.description})" if param.description else ""),
                )
            resolved[param.name] = param.default
            continue
        ok, value = check_value(param.type, value)
        if not ok:
            problems.add(
                *where(param.name, param),
                f"{prefix}parameter '{param.name}' must be "
                f"{describe_type(param.type)}, not {value!r}",
            )
        resolved[param.name] = value
    problems.problems.sort(key=lambda p: p.line)
    problems.raise_if_any()
    return resolved

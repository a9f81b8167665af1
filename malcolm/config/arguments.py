"""Check a section's keys against the constructor they will be passed to.

Everything here reads signatures and annotations; nothing is called. A
section's keys are keyword arguments: each must be a keyword the factory
takes (unless it takes ``**kwargs``), every keyword without a default must
be given, and a keyword annotated with a simple type (``str``, ``float``,
``int``, ``bool``, ``Path``, maybe ``| None``) must get a value of it.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Mapping
from typing import Any

from malcolm.hooks.signature import signature_of

from .errors import Problem, did_you_mean

__all__ = ["argument_problems", "factory_name", "needs"]

_KEYWORDS = (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)


def factory_name(factory: Callable[..., Any]) -> str:
    """The name a message gives ``factory`` (its qualified name)."""
    return getattr(factory, "__qualname__", None) or repr(factory)


def _parameters(factory: Callable[..., Any]) -> Mapping[str, inspect.Parameter] | None:
    sig = signature_of(factory)
    return None if sig is None else sig.parameters


def needs(factory: Callable[..., Any], name: str) -> bool:
    """True if ``factory`` has a keyword ``name`` without a default."""
    params = _parameters(factory)
    param = None if params is None else params.get(name)
    return (
        param is not None and param.kind in _KEYWORDS and param.default is param.empty
    )


def default_of(factory: Callable[..., Any], name: str) -> tuple[bool, Any]:
    """``(True, default)`` if keyword ``name`` of ``factory`` has a default."""
    params = _parameters(factory)
    param = None if params is None else params.get(name)
    if param is None or param.kind not in _KEYWORDS or param.default is param.empty:
        return False, None
    return True, param.default


def argument_problems(
    factory: Callable[..., Any],
    kwargs: Mapping[str, Any],
    kind: str,
    file: str,
    line: int,
    param_lines: Mapping[str, int],
) -> list[Problem]:
    """Why ``factory(**kwargs)`` would be refused, found from its signature.

    An unknown keyword or a value of the wrong type is reported at the line
    of its key, a missing one at ``line``. A factory whose signature cannot
    be read is not checked.
    """
    params = _parameters(factory)
    if params is None:
        return []
    problems: list[Problem] = []
    takes = [n for n, p in params.items() if p.kind in _KEYWORDS]
    var_kw = any(p.kind is p.VAR_KEYWORD for p in params.values())
    for key in kwargs:
        if key not in takes and not var_kw:
            problems.append(
                Problem(
                    file,
                    param_lines.get(key, line),
                    f"{kind}: unknown parameter '{key}' "
                    f"({factory_name(factory)} takes {', '.join(takes) or 'nothing'})"
                    + did_you_mean(key, takes),
                )
            )
    for name in takes:
        param = params[name]
        if param.default is param.empty and name not in kwargs:
            problems.append(
                Problem(file, line, f"{kind}: missing required parameter '{name}'")
            )
    for key, value in kwargs.items():
        want = _annotation(factory, key)
        if want is not None and not _fits(value, want):
            problems.append(
                Problem(
                    file,
                    param_lines.get(key, line),
                    f"{kind}: '{key}' must be {_say(want)}, not {value!r}",
                )
            )
    return problems


_SIMPLE = {"str": (str,), "float": (int, float), "int": (int,), "bool": (bool,)}


def _annotation(factory: Any, key: str) -> str | None:
    """The simple type (str/float/int/bool, maybe "| None") a keyword declares."""
    target = factory.__init__ if inspect.isclass(factory) else factory
    raw = getattr(target, "__annotations__", {}).get(key)
    if not isinstance(raw, str):
        raw = getattr(raw, "__name__", None) if raw is not None else None
    if raw is None:
        return None
    parts = {p.strip() for p in raw.split("|")}
    if parts - {"None"} and parts - {"None"} <= set(_SIMPLE) | {"Path"}:
        return " or ".join(sorted(parts))
    return None


def _fits(value: Any, want: str) -> bool:
    parts = set(want.split(" or "))
    if value is None:
        return "None" in parts
    if isinstance(value, bool):
        return "bool" in parts
    for name in parts:
        if name == "Path" and isinstance(value, str):
            return True
        if name in _SIMPLE and isinstance(value, _SIMPLE[name]):
            return True
    return False


_WORDS = {"str": "text", "float": "a number", "int": "an integer",
          "bool": "a boolean", "Path": "a path"}  # fmt: skip


def _say(want: str) -> str:
    parts = want.split(" or ")
    words = sorted({_WORDS[p] for p in parts if p in _WORDS})
    return " or ".join(words) + (" (or nothing)" if "None" in parts else "")

"""Build a MethodMeta from a Python function's signature and annotations."""

from __future__ import annotations

import inspect
from collections.abc import Callable
from typing import Any, get_type_hints

from malcolm.core import BooleanMeta, MapMeta, Meta, MethodMeta, NumberMeta, StringMeta


def meta_for(annotation: Any, description: str = "") -> Meta:
    """The meta for a Python annotation (int, float, str, bool)."""
    if annotation is bool:
        return BooleanMeta(description, writeable=True)
    if annotation is int:
        return NumberMeta("int64", description, writeable=True)
    if annotation is float:
        return NumberMeta("float64", description, writeable=True)
    return StringMeta(description, writeable=True)


def method_meta_from(
    func: Callable[..., Any], returns: MapMeta | None = None
) -> MethodMeta:
    """Takes from the parameters (required when they have no default)."""
    sig = inspect.signature(func)
    try:
        hints = get_type_hints(func)
    except Exception:
        hints = {}
    elements: dict[str, Meta] = {}
    required: list[str] = []
    defaults: dict[str, Any] = {}
    for name, p in sig.parameters.items():
        if name == "self" or p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD):
            continue
        elements[name] = meta_for(hints.get(name, str), name)
        if p.default is p.empty:
            required.append(name)
        else:
            defaults[name] = p.default
    doc = inspect.getdoc(func) or ""
    return MethodMeta(
        MapMeta(elements, required),
        returns or MapMeta(),
        defaults,
        description=doc.splitlines()[0] if doc else "",
    )

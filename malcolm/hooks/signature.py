"""What a hook function must accept, checked when it is registered.

A hook function is called with up to two positional arguments, ``(task,
device)``: it may take none, one or both (or ``*args``), and anything else it
declares must have a default.
"""

from __future__ import annotations

import inspect
import math
import threading
import types
import weakref
from collections.abc import Callable
from typing import Any

_POSITIONAL = (
    inspect.Parameter.POSITIONAL_ONLY,
    inspect.Parameter.POSITIONAL_OR_KEYWORD,
)

# what is read from a function or class once: by the function itself, or
# (for a method bound to any instance, the same for every instance) by the
# function it binds, in a table of its own
_PLAIN: weakref.WeakKeyDictionary[Any, dict[str, Any]] = weakref.WeakKeyDictionary()
_BOUND: weakref.WeakKeyDictionary[Any, dict[str, Any]] = weakref.WeakKeyDictionary()
_LOCK = threading.Lock()


def _once(func: Callable[..., Any], what: str, read: Callable[[], Any]) -> Any:
    """``read()``, kept as ``what`` of ``func`` (see the tables above)."""
    if isinstance(func, types.MethodType) and inspect.isfunction(func.__func__):
        table, key = _BOUND, func.__func__
    elif inspect.isfunction(func) or inspect.isclass(func):
        table, key = _PLAIN, func
    else:  # another kind of callable: nothing to key on safely
        return read()
    with _LOCK:
        known = table.get(key)
        if known is not None and what in known:
            return known[what]
    value = read()
    with _LOCK:
        table.setdefault(key, {})[what] = value
    return value


def _read(func: Callable[..., Any]) -> inspect.Signature | None:
    try:
        return inspect.signature(func)
    except (TypeError, ValueError):
        return None


def signature_of(func: Callable[..., Any]) -> inspect.Signature | None:
    """``inspect.signature(func)`` (None if it cannot be read), read once per
    function or class: a method bound to any instance of a class is read
    once for all of them. Building a thousand blocks of one part class reads
    its hook functions' and constructor's signatures once."""
    return _once(func, "signature", lambda: _read(func))


def hook_problem(func: Callable[..., Any]) -> str | None:
    """Why ``func`` cannot be called as ``func(task, device)``, or None
    (worked out once per function, as :func:`signature_of`)."""
    if not callable(func):
        name = getattr(func, "__qualname__", None) or repr(func)
        return f"{name} is not callable"
    return _once(func, "problem", lambda: _hook_problem(func))


def hook_nargs(func: Callable[..., Any]) -> int:
    """How many of ``(task, device)`` a hook function takes (it has no
    :func:`hook_problem`)."""
    return _once(func, "nargs", lambda: _hook_nargs(func))


def _hook_problem(func: Callable[..., Any]) -> str | None:
    name = getattr(func, "__qualname__", None) or repr(func)
    sig = signature_of(func)
    if sig is None:
        return f"{name}: its signature cannot be read"
    params = list(sig.parameters.values())
    required = [
        p.name for p in params if p.kind in _POSITIONAL and p.default is p.empty
    ]
    if len(required) > 2:
        return (
            f"{name}({', '.join(required)}) needs {len(required)} arguments; a hook"
            " function is called with (task, device)"
        )
    keywords = [
        p.name
        for p in params
        if p.kind == inspect.Parameter.KEYWORD_ONLY and p.default is p.empty
    ]
    if keywords:
        return (
            f"{name} needs keyword argument(s) {', '.join(keywords)}; a hook"
            " function is called with (task, device)"
        )
    return None


def _hook_nargs(func: Callable[..., Any]) -> int:
    sig = signature_of(func)
    assert sig is not None  # hook_problem says so otherwise
    params = sig.parameters.values()
    if any(p.kind == inspect.Parameter.VAR_POSITIONAL for p in params):
        return 2
    return min(2, sum(1 for p in params if p.kind in _POSITIONAL))


def timeout_problem(name: str, value: Any, allow_none: bool = True) -> str | None:
    """Why ``value`` is not a usable timeout in seconds (positive, finite), or None."""
    if value is None and allow_none:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float):
        return f"{name} must be a number of seconds, not {value!r}"
    if not math.isfinite(value) or value <= 0:
        return f"{name} must be a positive, finite number of seconds, not {value!r}"
    return None

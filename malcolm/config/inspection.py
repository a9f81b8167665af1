"""What a section's class tells without being made: its hook functions and
timeouts, read from the class and the section's keys, nothing called.

``malcolm check`` relies on this to find the problems a constructor or
``Controller.add_part`` would find later, without running a user's code:
a hook function that cannot be called as ``(task, device)``, and a
``phase_timeout`` (or one of ``phase_timeouts``) that is not a positive,
finite number of seconds.
"""

from __future__ import annotations

import inspect
import types
from collections.abc import Callable, Iterator, Mapping
from typing import Any

from malcolm.hooks.signature import hook_problem, timeout_problem
from malcolm.parts.base import phase_functions

from .arguments import default_of, factory_name

__all__ = ["hook_functions", "hook_problems", "timeout_problems"]

#: ``(path below the section's keys, message)``: where and what is wrong
Located = tuple[tuple[Any, ...], str]


class _Unmade:
    """Stands for the instance a method would be bound to: never called."""


def hook_functions(cls: type) -> Iterator[tuple[str, Callable[..., Any]]]:
    """``(phase, function as an instance would have it)`` for every
    phase-decorated attribute of ``cls``, as ``Part.hook_functions`` finds
    them on an instance (the first definition of a name in the MRO wins)."""
    for phase, _, value in phase_functions(cls):
        yield phase, _as_bound(cls, value)


def _as_bound(cls: type, value: Any) -> Callable[..., Any]:
    if isinstance(value, staticmethod):
        return value.__func__
    if isinstance(value, classmethod):
        return types.MethodType(value.__func__, cls)
    if inspect.isfunction(value):
        return types.MethodType(value, _Unmade())
    return value


def hook_problems(cls: type, part: str) -> list[str]:
    """Why each hook function of ``cls`` could not be called with
    ``(task, device)``, as ``part 'x', phase P: ...`` messages."""
    out = []
    for phase, func in hook_functions(cls):
        problem = hook_problem(func)
        if problem is not None:
            out.append(f"part {part!r}, phase {phase}: {problem}")
    return out


def timeout_problems(
    factory: Callable[..., Any], kwargs: Mapping[str, Any]
) -> list[Located]:
    """Bad ``phase_timeout``/``phase_timeouts`` of a controller section, given
    or (for ``phase_timeout``) the factory's default."""
    out: list[Located] = []
    if "phase_timeout" in kwargs:
        problem = timeout_problem("phase_timeout", kwargs["phase_timeout"])
        if problem:
            out.append((("phase_timeout",), problem))
    else:
        has_default, default = default_of(factory, "phase_timeout")
        problem = timeout_problem("phase_timeout", default) if has_default else None
        if problem:
            out.append(((), f"{problem} (the default of {factory_name(factory)})"))
    timeouts = kwargs.get("phase_timeouts")
    if timeouts is None:
        return out
    if not isinstance(timeouts, Mapping):
        where = ("phase_timeouts",)
        out.append((where, "phase_timeouts must map phase names to seconds"))
        return out
    for phase, seconds in timeouts.items():
        problem = timeout_problem(f"phase_timeouts.{phase}", seconds, False)
        if problem:
            out.append((("phase_timeouts", phase), problem))
    return out

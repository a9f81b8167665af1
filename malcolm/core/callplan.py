"""A method's call plan: its arguments checked by code made once per meta.

:func:`plan_args` turns a :class:`~malcolm.core.MethodMeta` into one
generated function ``args(meta, params)`` that does what
``meta.validate_args(where, params)`` does, every argument in line: a
string argument of a ``StringMeta`` taken as it is, the others through
their meta's ``validate`` (read live: a meta changed in place is seen), a
default validated once when the plan is made (a scalar one; any other is
copied per call, as ``validate_args`` does), the same errors word for word
(``BadValueError: <where>.<arg>: ...``). Anything else (arguments that are
not a dict, an unknown argument) goes to ``validate_args`` itself.

The plan holds what it was made from: the meta, its ``takes`` and the
takes' ``elements``, ``required`` and the ``defaults`` (copies, compared
per call in C); if any differs (an Editor or Export change, a meta whose
takes or defaults were replaced or changed in place) it answers None and
its caller makes a new plan (``Controller.call``, held by the
:class:`~malcolm.core.Method` as ``args_plan``).
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from typing import Any, Protocol

from .errors import BadValueError
from .metas import (
    _IMMUTABLE,
    BooleanMeta,
    ChoiceMeta,
    MethodMeta,
    NumberMeta,
    StringMeta,
)

__all__ = ["ArgsPlan", "plan_args"]

#: metas whose validate gives a scalar
_SCALAR_METAS = (StringMeta, NumberMeta, BooleanMeta, ChoiceMeta)


class ArgsPlan(Protocol):
    """``plan(meta, params)``: the validated arguments, or None if the plan
    is not ``meta``'s as it is now (make a new one)."""

    #: whether the arguments it gives are all scalars (str, int, float,
    #: bool, None): every argument's meta gives one, every default is one
    scalars: bool

    def __call__(self, meta: MethodMeta, params: Any) -> dict[str, Any] | None: ...


def _same_defaults(snapshot: dict[str, Any]) -> Callable[[dict[str, Any]], bool]:
    """A test that defaults are still ``snapshot``'s (a default that is not
    a scalar by identity: it is copied from the meta per call anyway)."""

    def same(defaults: dict[str, Any]) -> bool:
        if defaults.keys() != snapshot.keys():
            return False
        for key, was in snapshot.items():
            now = defaults[key]
            if now is not was and (
                type(now) not in _IMMUTABLE or type(now) is not type(was) or now != was
            ):
                return False
        return True

    return same


def plan_args(meta: MethodMeta, where: str) -> ArgsPlan:
    """The arguments' plan of ``meta`` for the method named ``where``
    (``<mri>.<method>``, what errors name); see the module's docstring."""
    takes = meta.takes
    elements = dict(takes.elements)
    defaults = meta.defaults
    ns: dict[str, Any] = {
        "META": meta,
        "TAKES": takes,
        "ELEMENTS": elements,
        "REQUIRED": copy.copy(takes.required),
        "NAMES": frozenset(elements),
        "SLOW": meta.validate_args,
        "WHERE": where,
        "BadValueError": BadValueError,
    }
    if all(type(v) in _IMMUTABLE for v in defaults.values()):
        # one comparison in C (meta and takes by identity: no __eq__)
        ns["SNAPSHOT"] = (meta, takes, elements, ns["REQUIRED"], dict(defaults))
        stale = [
            "    if (meta, takes, takes.elements, takes.required, meta.defaults)"
            " != SNAPSHOT:"
        ]
    else:
        ns["SAME_DEFAULTS"] = _same_defaults(dict(defaults))
        stale = [
            "    if (meta is not META or takes is not TAKES"
            " or takes.elements != ELEMENTS or takes.required != REQUIRED"
            " or not SAME_DEFAULTS(meta.defaults)):"
        ]
    lines = [
        "def args(meta, params):",
        "    takes = meta.takes",
        *stale,
        "        return None",
        "    if type(params) is not dict or not NAMES >= params.keys():",
        "        return SLOW(WHERE, params or {})",
        "    out = {}",
    ]
    for i, (name, arg_meta) in enumerate(elements.items()):
        key = repr(name)
        prefix = repr(f"{where}.{name}: ")
        ns[f"V{i}"] = arg_meta.validate
        lines.append(f"    v = params.get({key})")
        lines.append("    if v is not None:")
        check = [
            "try:",
            f"    v = V{i}(v)",
            "except BadValueError as e:",
            f"    raise BadValueError({prefix} + str(e)) from None",
        ]
        if type(arg_meta) is StringMeta:  # a str is its own validation
            lines.append("        if type(v) is not str:")
            lines += [f"            {line}" for line in check]
        else:
            lines += [f"        {line}" for line in check]
        lines.append(f"        out[{key}] = v")
        if name in defaults:
            default = defaults[name]
            if type(default) in _IMMUTABLE:  # validated now, once
                ns[f"D{i}"] = meta._default(name, arg_meta)
                lines.append(f"    else:\n        out[{key}] = D{i}")
            else:  # copied per call, as validate_args does
                ns[f"M{i}"] = arg_meta
                lines.append(
                    f"    else:\n        out[{key}] = META._default({key}, M{i})"
                )
        elif name in takes.required:
            text = repr(f"{where}.{name}: missing required argument")
            lines.append(f"    else:\n        raise BadValueError({text})")
    lines.append("    return out\n")
    exec(compile("\n".join(lines), f"<args {where}>", "exec"), ns)
    plan: ArgsPlan = ns["args"]
    plan.scalars = all(type(m) in _SCALAR_METAS for m in elements.values()) and all(
        type(v) in _IMMUTABLE for v in defaults.values()
    )
    return plan

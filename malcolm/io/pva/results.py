"""What a pvAccess method call names and passes, and what it gets back.

interop.md §2's three call forms: the block's channel with pvRequest
``{method: "<name>"}`` and the arguments as the value (what GDA sends); the
method's own channel ``<mri>.<method>``; an ``epics:nt/NTURI:1.0`` whose
``path`` is ``<mri>.<method>`` and whose ``query`` holds the arguments.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any

from p4p import Value

from malcolm.core import BadValueError

from .convert import (
    STRUCTURE,
    _fill,
    _freeze,
    _type,
    map_to_value,
    meta_value_spec,
    to_dict,
)

NTURI = "epics:nt/NTURI:1.0"

# (id of a returns meta's elements, a result's keys) -> (those elements, the
# result's spec and Type): a method's result typed by its metas alone has
# the same type each call (the elements are kept, so their id is not reused)
_RESULT_TYPES: dict[tuple[int, tuple[str, ...]], tuple[Any, Any, Any, Any]] = {}
_RESULT_TYPES_MAX = 256

# a scalar field's code -> the Python types a Value takes for it as they are
_SCALAR_FITS: dict[str, tuple[type, ...]] = {
    **{code: (int,) for code in "bBhHiIlL"},
    "f": (float, int),
    "d": (float, int),
    "s": (str,),
    "?": (bool,),
}

# where a pvRequest may carry the method's name
_METHOD_PLACES = ("method", "record._options.method", "field.method")


@lru_cache(maxsize=1)
def version_tag() -> str:
    """``version:malcolm:<version>``, the tag §2 puts in every block meta."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return f"version:malcolm:{version('malcolm')}"
    except PackageNotFoundError:
        return "version:malcolm:unknown"


def _request_method(request: Any) -> str | None:
    if not isinstance(request, Value):
        return None
    for place in _METHOD_PLACES:
        try:
            name = request[place]
        except (KeyError, AttributeError, TypeError, ValueError):
            continue
        if isinstance(name, str) and name:
            return name
    return None


def _args(value: Any, where: str) -> dict[str, Any]:
    if value is None:
        return {}
    args = to_dict(value)
    if not isinstance(args, dict):
        raise BadValueError(f"{where}: the arguments must be a structure")
    args.pop("typeid", None)
    return args


def method_args(
    path: list[str], value: Any, request: Any
) -> tuple[str, str, dict[str, Any]]:
    """``(mri, method, arguments)`` of a call on the channel of ``path``;
    ``request`` is the pvRequest, or a function giving it (called only for
    a call on a block's channel, the one form that reads it)."""
    channel = ".".join(path)
    if isinstance(value, Value) and value.getID() == NTURI:
        try:
            target = value["path"]
        except (KeyError, ValueError):
            target = ""
        mri, dot, method = str(target).rpartition(".")
        if not (dot and mri and method):
            raise BadValueError(
                f"{channel}: NTURI path {target!r} is not '<mri>.<method>'"
            )
        try:
            query = value["query"]
        except (KeyError, ValueError):
            query = None
        return mri, method, _args(query, f"{target}: query")
    if len(path) == 2:
        return path[0], path[1], _args(value, channel)
    method = _request_method(request() if callable(request) else request)
    if method is None:
        raise BadValueError(
            f"{channel}: a call on a block's channel needs the method's name in "
            "the pvRequest ({method: '<name>'}), or use channel <mri>.<method>"
        )
    return path[0], method, _args(value, f"{channel}.{method}")


def result_value(result: Any, returns: Any, memo: list[Any] | None = None) -> Value:
    """A method's result as the Value an RPC returns, typed by its ``returns``
    MapMeta where it says. ``memo`` (a caller's list) is set to
    ``[returns, ((key, type), ...), Type]`` when the result's every field
    is a scalar of a type its field takes as it is: a result of those keys
    and exact types (in order), for that same ``returns`` object, is then
    ``Value(Type, result)`` (what this returns for it), without a call."""
    if result is None:
        result = {}
    if not isinstance(result, dict):
        result = {"value": result}
    elements = returns.get("elements") if isinstance(returns, dict) else None
    if isinstance(elements, dict) and "typeid" not in result:
        key = (id(elements), tuple(result))
        known = _RESULT_TYPES.get(key)
        if known is None or known[0] is not elements:
            if not all(elements.get(k) for k in result):
                return map_to_value(result, elements)  # typed by what it holds
            fields = [(k, meta_value_spec(elements[k])) for k in result]
            spec = _freeze(("S", STRUCTURE, fields))
            if len(_RESULT_TYPES) >= _RESULT_TYPES_MAX:
                _RESULT_TYPES.clear()
            scalars = tuple(_SCALAR_FITS.get(sub) for _, sub in fields)
            if None in scalars:
                scalars = None
            known = _RESULT_TYPES[key] = (elements, spec, _type(spec), scalars)
        scalars = known[3]
        if scalars is not None and all(
            type(v) in fit for v, fit in zip(result.values(), scalars)
        ):  # every field a scalar of a type it takes as it is
            if memo is not None:
                memo[:] = [
                    returns,
                    tuple(zip(result, map(type, result.values()))),
                    known[2],
                ]
            return Value(known[2], result)
        return Value(known[2], _fill(known[1], result))
    return map_to_value(result, elements)

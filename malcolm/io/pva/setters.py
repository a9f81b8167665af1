"""Precompiled assignment of a change's data into a channel's ``Value``.

A channel's monitor update is a ``Value`` of the channel's type in which
only the changed leaves are set. :func:`compile_setter` turns the type spec
of one field (:func:`malcolm.io.pva.convert.spec_at`) into a function
``setter(value, data) -> bool`` that checks ``data`` still fits that type
(as :func:`~malcolm.io.pva.convert.fits` does) and sets its leaves (as
:func:`~malcolm.io.pva.convert.assign` does), walking the spec once when
compiled instead of once per change. False means the data does not fit:
the caller drops the half-filled ``Value`` and takes the general path.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from p4p import Value

from .convert import STRUCTURE, Spec, _fill, fits

__all__ = ["Setter", "compile_setter"]

Setter = Callable[[Value, Any], bool]

_METHOD_LOG = "malcolm:core/MethodLog:1.0"

# the Python types that fit a scalar code as they are (bool is not an int here)
_EXACT: dict[str, tuple[type, ...]] = {
    **{code: (int,) for code in "bBhHiIlL"},
    "f": (float, int),
    "d": (float, int),
    "s": (str,),
    "?": (bool,),
}


def compile_setter(spec: Spec, dotted: str, subset: bool = False) -> Setter:
    """A setter of the field ``dotted`` (``""``: the whole value) of type
    ``spec``; ``subset``: a structure may hold fewer fields (a MethodLog's
    value)."""
    if isinstance(spec, tuple):
        return _struct_setter(spec, dotted, subset)
    exact = _EXACT.get(spec)
    if exact is not None:

        def scalar(value: Value, data: Any) -> bool:
            if type(data) in exact:
                value[dotted] = data
                return True
            if fits(spec, data):  # numpy scalars and the like
                value[dotted] = _fill(spec, data)
                return True
            return False

        return scalar

    def general(value: Value, data: Any) -> bool:
        if fits(spec, data):
            value[dotted] = _fill(spec, data)
            return True
        return False

    return general


def _struct_setter(spec: Spec, dotted: str, subset: bool) -> Setter:
    typeid = spec[1]
    names = tuple(k for k, _ in spec[2])
    typed = ("typeid", *names)
    allowed = frozenset(names)
    log = typeid == _METHOD_LOG
    prefix = f"{dotted}." if dotted else ""
    children = [
        (k, compile_setter(sub, prefix + k, log and k == "value")) for k, sub in spec[2]
    ]

    def struct(value: Value, data: Any) -> bool:
        if not isinstance(data, dict):
            return False
        if data.get("typeid", STRUCTURE) != typeid:
            return False
        keys = tuple(data)
        if keys != typed and keys != names:
            plain = [k for k in keys if k != "typeid"]  # the typeid elsewhere
            if not (set(plain) <= allowed if subset else tuple(plain) == names):
                return False
        for key, setter in children:
            sub = data.get(key)
            if sub is not None and not setter(value, sub):
                return False
        return True

    return struct

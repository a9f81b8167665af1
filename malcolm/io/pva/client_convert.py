"""The client side's conversions between p4p ``Value``\\s and plain data.

(What a server sends becomes plain data with :func:`.convert.to_dict`.)
:func:`args_value` builds the ``Value`` of a method call's arguments from
plain data, each argument typed by the method's ``takes`` meta where it says
(a table, an array of int32...), else by the Python value (a dict with a
``typeid`` is a structure with that id, a list of dicts a variant array).
:func:`remote_error` turns an RPC error's text, ``"<ExceptionType>:
<message>"`` (interop.md §2), back into that malcolm exception.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from p4p import Type, Value

from malcolm.core import (
    AbortedError,
    BadValueError,
    MalcolmError,
    NotAllowedError,
    NotFoundError,
    NotWriteableError,
    PhaseTimeoutError,
    WaitTimeoutError,
)
from malcolm.core.metas import (
    BooleanArrayMeta,
    BooleanMeta,
    ChoiceArrayMeta,
    ChoiceMeta,
    MapMeta,
    Meta,
    NumberArrayMeta,
    NumberMeta,
    StringArrayMeta,
    StringMeta,
    TableMeta,
)

from .convert import DTYPE_CODES

__all__ = ["RemoteError", "args_value", "remote_error", "value_type"]


class RemoteError(MalcolmError):
    """A remote block refused or failed, with an exception type this process
    does not know; the message is the server's whole text."""


#: exception type names a server sends -> the class re-raised here
ERRORS: dict[str, type[Exception]] = {
    cls.__name__: cls
    for cls in (
        AbortedError,
        BadValueError,
        MalcolmError,
        NotAllowedError,
        NotFoundError,
        NotWriteableError,
        PhaseTimeoutError,
        WaitTimeoutError,
    )
}
ERRORS.update(
    {
        "ValueError": BadValueError,
        "TypeError": BadValueError,
        "KeyError": NotFoundError,
        "LookupError": NotFoundError,
    }
)


def remote_error(text: str, where: str = "") -> Exception:
    """The exception an RPC or put error's text stands for.

    ``"NotAllowedError: SCAN: run() is not allowed..."`` gives
    ``NotAllowedError("SCAN: run() is not allowed...")``; a type this side
    does not know gives a :class:`RemoteError` with the whole text; ``where``
    (e.g. ``"pva://127.0.0.1:5075 SCAN.run"``) is put before text that has
    no type.
    """
    kind, sep, message = str(text).partition(": ")
    cls = ERRORS.get(kind) if sep and kind.isidentifier() else None
    if cls is not None:
        return cls(message)
    if sep and kind.isidentifier() and kind.endswith(("Error", "Exception")):
        return RemoteError(str(text))
    return RemoteError(f"{where}: {text}" if where else str(text))


# ---- plain data -> Value
def _code_of_list(items: list[Any]) -> str | None:
    if not items:
        return None
    if all(isinstance(i, bool) for i in items):
        return "a?"
    if all(isinstance(i, int) and not isinstance(i, bool) for i in items):
        return "al"
    if all(isinstance(i, int | float) and not isinstance(i, bool) for i in items):
        return "ad"
    if all(isinstance(i, str) for i in items):
        return "as"
    return "av"


def _meta_code(meta: Meta | None) -> Any:
    """The pvData type of a value the meta describes, None if it says nothing."""
    if isinstance(meta, NumberMeta):
        return DTYPE_CODES.get(meta.dtype, "d")
    if isinstance(meta, NumberArrayMeta):
        return "a" + DTYPE_CODES.get(meta.dtype, "d")
    if isinstance(meta, BooleanMeta):
        return "?"
    if isinstance(meta, BooleanArrayMeta):
        return "a?"
    if isinstance(meta, StringMeta | ChoiceMeta):
        return "s"
    if isinstance(meta, StringArrayMeta | ChoiceArrayMeta):
        return "as"
    if isinstance(meta, TableMeta):
        fields = [(k, _meta_code(m) or "av") for k, m in meta.elements.items()]
        return ("S", "malcolm:core/Table:1.0", fields)
    return None


def value_type(value: Any, meta: Meta | None = None) -> Any:
    """The pvData type (a code, or an ``("S", id, fields)`` tuple) of ``value``."""
    code = _meta_code(meta)
    if code is not None:
        return code
    if isinstance(value, np.ndarray):
        code = DTYPE_CODES.get(str(value.dtype))
        if code is not None:
            return "a" + code
        value = value.tolist()
    if isinstance(value, bool):
        return "?"
    if isinstance(value, int):
        return "l"
    if isinstance(value, float):
        return "d"
    if isinstance(value, str):
        return "s"
    if isinstance(value, Mapping):
        typeid = str(value.get("typeid", "structure"))
        fields = [(str(k), value_type(v)) for k, v in value.items() if k != "typeid"]
        return ("S", typeid, fields)
    if isinstance(value, list | tuple):
        return _code_of_list(list(value)) or "av"
    return "v"


def _fill(value: Any, code: Any) -> Any:
    """``value`` in the form p4p assigns to a field of type ``code``."""
    if isinstance(code, tuple):
        typeid = code[1]
        if typeid == "malcolm:core/Table:1.0" and isinstance(value, list | tuple):
            columns = [k for k, _ in code[2]]
            value = {c: [row.get(c) for row in value] for c in columns}
        fields = dict(code[2])
        return {
            k: _fill(v, fields[k])
            for k, v in dict(value).items()
            if k != "typeid" and k in fields
        }
    if code == "av":
        return [_variant(v) for v in value]
    if code == "v":
        return _variant(value)
    if isinstance(value, np.ndarray):
        return value
    if isinstance(value, tuple):
        return list(value)
    return value


def _variant(value: Any) -> Any:
    """What goes in a variant field: a Value for a structure, else the value."""
    if isinstance(value, Mapping):
        code = value_type(value)
        return Value(Type(code[2], id=code[1]), _fill(value, code))
    if isinstance(value, list | tuple) and value and isinstance(value[0], Mapping):
        return [_variant(v) for v in value]
    return value


def args_value(args: Mapping[str, Any], takes: MapMeta | None = None) -> Value:
    """The ``Value`` of a method call's arguments (``None`` ones left out)."""
    elements = takes.elements if takes is not None else {}
    fields = []
    data = {}
    for name, value in args.items():
        if value is None:
            continue
        code = value_type(value, elements.get(name))
        fields.append((name, code))
        data[name] = _fill(value, code)
    return Value(Type(fields), data)

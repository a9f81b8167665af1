"""Malcolm structures <-> p4p ``Value``s, with the typeids of interop.md §2.

Both the pvAccess server and its client use these:

- :func:`to_value` makes a ``p4p.Value`` of plain data (the dicts with
  ``typeid`` keys that ``to_dict()`` gives: a block, a field, a meta, a
  generator...). Each dict becomes a structure whose id is its ``typeid``
  (``structure`` if it has none). An attribute's ``value`` is typed by its
  meta (``NumberMeta`` int32 -> ``int32_t``, a ``TableMeta`` -> a structure
  of column arrays...), so that the type of a channel stays the same while
  its values change; a method's ``took``/``returned`` values are structures
  typed by its ``takes``/``returns`` elements, its ``defaults`` by
  ``takes``. Other data is typed by what it holds: str ``string``, bool
  ``boolean``, int ``long``, float ``double``, a list of strings
  ``string[]``, of numbers ``long[]``/``double[]``, anything else (dicts,
  empty lists) ``any[]``; a generator (``PointGeneratorMeta``) is ``any``.
- :func:`to_dict` goes back: a ``Value`` (or what a field of one holds) as
  plain data, each structure a dict whose ``typeid`` is its id (none for a
  plain ``structure``), arrays as lists, numbers as int/float. For every
  block ``to_dict(to_value(d)) == d``.
- :func:`value_type` is the ``p4p.Type`` :func:`to_value` uses (cached by
  shape), :func:`type_spec` the same as p4p's nested-tuple spec.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from functools import lru_cache
from typing import Any

import numpy as np
from p4p import Type, Value

__all__ = [
    "DTYPE_CODES",
    "STRUCTURE",
    "assign",
    "map_to_value",
    "fits",
    "meta_value_spec",
    "spec_at",
    "to_dict",
    "to_value",
    "type_spec",
    "value_type",
]

#: the id of a structure that has no typeid
STRUCTURE = "structure"

#: NumberMeta dtype -> pvData type code
DTYPE_CODES = {
    "int8": "b",
    "uint8": "B",
    "int16": "h",
    "uint16": "H",
    "int32": "i",
    "uint32": "I",
    "int64": "l",
    "uint64": "L",
    "float32": "f",
    "float64": "d",
}

# fields whose pvData type the normative types fix (all others are inferred)
_FIXED = {
    ("alarm_t", "severity"): "i",
    ("alarm_t", "status"): "i",
    ("time_t", "nanoseconds"): "i",
    ("time_t", "userTag"): "i",
    ("display_t", "precision"): "i",
}
# list fields of metas and logs that are always string[] (also when empty)
_STRING_LISTS = frozenset(
    ("tags", "fields", "choices", "labels", "required", "present")
)

_NT_ATTRIBUTES = frozenset(
    (
        "epics:nt/NTScalar:1.0",
        "epics:nt/NTScalarArray:1.0",
        "epics:nt/NTTable:1.0",
    )
)
_METHOD = "malcolm:core/Method:1.1"
_METHOD_META = "malcolm:core/MethodMeta:1.1"
_METHOD_LOG = "malcolm:core/MethodLog:1.0"
#: what a scalar field of a Value is in Python (to_dict keeps it as it is)
_SCALAR_TYPES = frozenset({str, int, float, bool})
_TABLE = "malcolm:core/Table:1.0"

Spec = Any  # a p4p type code ("s", "ad", "v"...) or ("S", id, fields)


def _meta_kind(meta: Any) -> str:
    if isinstance(meta, Mapping):
        typeid = meta.get("typeid", "")
        if isinstance(typeid, str) and typeid.startswith("malcolm:core/"):
            return typeid[len("malcolm:core/") :].rsplit(":", 1)[0]
    return ""


def meta_value_spec(meta: Any) -> Spec:
    """The pvData type of a value that ``meta`` (a meta's plain data) describes."""
    kind = _meta_kind(meta)
    if kind == "NumberMeta":
        return DTYPE_CODES.get(meta.get("dtype", "float64"), "d")
    if kind == "NumberArrayMeta":
        return "a" + DTYPE_CODES.get(meta.get("dtype", "float64"), "d")
    if kind in ("StringMeta", "ChoiceMeta"):
        return "s"
    if kind == "BooleanMeta":
        return "?"
    if kind in ("StringArrayMeta", "ChoiceArrayMeta"):
        return "as"
    if kind == "BooleanArrayMeta":
        return "a?"
    if kind == "TableMeta":
        elements = meta.get("elements") or {}
        return ("S", _TABLE, [(k, meta_value_spec(m)) for k, m in elements.items()])
    return "v"  # PointGeneratorMeta, or a meta this module does not know


def _map_spec(elements: Any, keys: Sequence[str] | None = None) -> Spec:
    """A structure with a field per element of a MapMeta (or per ``keys``)."""
    elements = elements if isinstance(elements, Mapping) else {}
    names = list(elements) if keys is None else list(keys)
    return ("S", STRUCTURE, [(k, meta_value_spec(elements.get(k))) for k in names])


def _infer(data: Any) -> Spec:
    """The pvData type of data without a meta to say what it is."""
    if isinstance(data, Mapping):
        return _struct_spec(data)
    if isinstance(data, bool | np.bool_):
        return "?"
    if isinstance(data, int | np.integer):
        return "l"
    if isinstance(data, float | np.floating):
        return "d"
    if isinstance(data, str):
        return "s"
    if isinstance(data, np.ndarray):
        if data.dtype.kind in "iu":
            return "al"
        if data.dtype.kind == "f":
            return "ad"
        if data.dtype.kind == "b":
            return "a?"
        data = data.tolist()
    if isinstance(data, Sequence) and not isinstance(data, bytes):
        if not data:
            return "av"
        if all(isinstance(x, str) for x in data):
            return "as"
        if all(isinstance(x, bool | np.bool_) for x in data):
            return "a?"
        if all(
            isinstance(x, int | np.integer) and not isinstance(x, bool) for x in data
        ):
            return "al"
        if all(
            isinstance(x, int | float | np.number) and not isinstance(x, bool)
            for x in data
        ):
            return "ad"
        return "av"
    return "v"


def _struct_spec(data: Mapping[str, Any]) -> Spec:
    typeid = data.get("typeid", STRUCTURE)
    if not isinstance(typeid, str) or not typeid:
        typeid = STRUCTURE
    fields: list[tuple[str, Spec]] = []
    if typeid == _METHOD:
        meta = data.get("meta") if isinstance(data.get("meta"), Mapping) else {}
        for key, sub in data.items():
            if key == "typeid":
                continue
            if key in ("took", "returned") and isinstance(sub, Mapping):
                which = "takes" if key == "took" else "returns"
                elements = (meta.get(which) or {}).get("elements")
                fields.append((key, _log_spec(sub, elements)))
            else:
                fields.append((key, _infer(sub)))
        return ("S", typeid, fields)
    for key, sub in data.items():
        if key == "typeid":
            continue
        fixed = _FIXED.get((typeid, key))
        if fixed is not None:
            spec = fixed
        elif key in _STRING_LISTS and isinstance(sub, Sequence | np.ndarray):
            spec = "as"
        elif key == "value" and typeid in _NT_ATTRIBUTES:
            spec = meta_value_spec(data.get("meta"))
        elif key == "defaults" and typeid == _METHOD_META and isinstance(sub, Mapping):
            spec = _map_spec((data.get("takes") or {}).get("elements"), list(sub))
        else:
            spec = _infer(sub)
        fields.append((key, spec))
    return ("S", typeid, fields)


def _log_spec(log: Mapping[str, Any], elements: Any) -> Spec:
    """A MethodLog whose value has a field per element of the method's map."""
    fields: list[tuple[str, Spec]] = []
    for key, sub in log.items():
        if key == "typeid":
            continue
        if key == "value":
            fields.append((key, _map_spec(elements)))
        else:
            fields.append((key, _struct_field(_METHOD_LOG, key, sub)))
    return ("S", log.get("typeid", _METHOD_LOG), fields)


def _struct_field(typeid: str, key: str, sub: Any) -> Spec:
    fixed = _FIXED.get((typeid, key))
    if fixed is not None:
        return fixed
    if key in _STRING_LISTS and isinstance(sub, Sequence | np.ndarray):
        return "as"
    return _infer(sub)


def _freeze(spec: Spec) -> Spec:
    if isinstance(spec, tuple | list) and spec and spec[0] in ("S", "aS"):
        return (spec[0], spec[1], tuple((k, _freeze(s)) for k, s in spec[2]))
    return spec


def type_spec(data: Mapping[str, Any]) -> Spec:
    """p4p's nested-tuple type spec ``("S", id, fields)`` of a Malcolm dict."""
    return _freeze(_infer(data))


@lru_cache(maxsize=1024)
def _type(spec: Spec) -> Type:
    return Type(_unfreeze(spec[2]), id=None if spec[1] == STRUCTURE else spec[1])


def _unfreeze(fields: Any) -> list[tuple[str, Any]]:
    out = []
    for key, spec in fields:
        if isinstance(spec, tuple) and spec[0] in ("S", "aS"):
            spec = (spec[0], spec[1], _unfreeze(spec[2]))
        out.append((key, spec))
    return out


def value_type(data: Mapping[str, Any]) -> Type:
    """The ``p4p.Type`` of :func:`to_value(data) <to_value>`."""
    return _type(type_spec(data))


def _variant(data: Any) -> Any:
    """What a p4p ``any`` field is given for ``data``."""
    if isinstance(data, Mapping):
        return to_value(data)
    if isinstance(data, Value):
        return data
    if isinstance(data, Sequence | np.ndarray) and not isinstance(data, str | bytes):
        code = _infer(data)
        return Value(Type([("value", code)]), {"value": _fill(code, data)})
    return data


def _fill(spec: Spec, data: Any) -> Any:
    """``data`` as what ``Value(type, ...)`` takes for a field of ``spec``."""
    if isinstance(spec, tuple):
        if not isinstance(data, Mapping):
            return {}
        out = {}
        for key, sub in spec[2]:
            if key in data and data[key] is not None:
                out[key] = _fill(sub, data[key])
        return out
    if spec == "v":
        return _variant(data)
    if spec == "av":
        return [_variant(x) for x in data]
    if spec == "as":
        return [str(x) for x in data]
    if isinstance(data, np.ndarray) or spec[0] != "a":
        return data
    return list(data)


def to_value(data: Mapping[str, Any], type: Type | None = None) -> Value:
    """A Malcolm dict (``to_dict()`` data) as a ``p4p.Value``, every field set."""
    spec = type_spec(data)
    return Value(type or _type(spec), _fill(spec, data))


def to_dict(value: Any) -> Any:
    """A ``p4p.Value`` (or a field's content) as plain Malcolm data.

    A MethodLog's value keeps only the arguments it lists as ``present``
    (its structure has a field for every one the method takes)."""
    if isinstance(value, Value):
        typeid = value.getID()
        # a structure of scalars (a call's arguments, most puts) in one C call
        flat = value.todict()
        if typeid != _METHOD_LOG and _SCALAR_TYPES.issuperset(map(type, flat.values())):
            return flat if typeid == STRUCTURE else {"typeid": typeid, **flat}
        out: dict[str, Any] = {}
        if typeid != STRUCTURE:
            out["typeid"] = typeid
        vtype = None  # the type, made (a copy) only if needed
        for key in value.keys():
            sub = value[key]
            if sub is None:
                if vtype is None:
                    vtype = value.type()
                if str(vtype[key]).startswith("a"):
                    sub = []  # p4p gives None for an empty numeric array
            out[key] = to_dict(sub)
        if typeid == _METHOD_LOG and isinstance(out.get("value"), dict):
            present = out.get("present") or []
            out["value"] = {k: v for k, v in out["value"].items() if k in present}
        return out
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, list | tuple):
        return [to_dict(x) for x in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def assign(value: Value, path: Sequence[str], data: Any, spec: Spec) -> None:
    """Set ``value[path]`` to ``data`` (of type ``spec``), marking only the
    leaves set, so a monitor update carries just them."""
    if isinstance(spec, tuple) and isinstance(data, Mapping):
        for key, sub in spec[2]:
            if key in data and data[key] is not None:
                assign(value, [*path, key], data[key], sub)
        return
    value[".".join(path)] = _fill(spec, data)


def spec_at(spec: Spec, path: Sequence[str]) -> Spec | None:
    """The spec of the field at ``path`` inside a structure's spec, or None."""
    for key in path:
        if not (isinstance(spec, tuple) and spec[0] == "S"):
            return None
        for name, sub in spec[2]:
            if name == key:
                spec = sub
                break
        else:
            return None
    return spec


def map_to_value(data: Mapping[str, Any], elements: Any = None) -> Value:
    """A plain structure (method arguments or results) as a ``Value``; fields
    that ``elements`` (a MapMeta's elements) describe are typed by their meta,
    the others by what they hold."""
    elements = elements if isinstance(elements, Mapping) else {}
    fields = []
    for key, sub in data.items():
        if key == "typeid":
            continue
        meta = elements.get(key)
        fields.append((key, meta_value_spec(meta) if meta else _infer(sub)))
    typeid = data.get("typeid", STRUCTURE)
    spec = _freeze(("S", typeid if isinstance(typeid, str) else STRUCTURE, fields))
    return Value(_type(spec), _fill(spec, data))


_INTEGER_CODES = frozenset("bBhHiIlL")


def fits(spec: Spec, data: Any, subset: bool = False) -> bool:
    """Whether ``data`` can be :func:`assign`-ed to a field of type ``spec``
    as it is (the type it would be given now is the same). ``subset``: a
    structure may hold fewer fields (a MethodLog's value lists which it
    holds in ``present``)."""
    if isinstance(spec, tuple):
        if not isinstance(data, Mapping):
            return False
        if data.get("typeid", STRUCTURE) != spec[1]:
            return False
        names = [k for k, _ in spec[2]]
        keys = [k for k in data if k != "typeid"]
        if subset:
            if not set(keys) <= set(names):
                return False
        elif keys != names:
            return False
        log = spec[1] == _METHOD_LOG
        return all(
            fits(sub, data[k], log and k == "value")
            for k, sub in spec[2]
            if k in data and data[k] is not None
        )
    if spec in ("v", "av"):
        return spec == "v" or isinstance(data, Sequence | np.ndarray)
    if spec.startswith("a"):
        if isinstance(data, str | bytes | Mapping) or not isinstance(
            data, Sequence | np.ndarray
        ):
            return False
        return all(fits(spec[1:], x) for x in data) if len(data) < 64 else True
    if spec == "s":
        return isinstance(data, str)
    if spec == "?":
        return isinstance(data, bool | np.bool_)
    if isinstance(data, bool | np.bool_) or not isinstance(
        data, int | float | np.number
    ):
        return False
    return spec not in _INTEGER_CODES or isinstance(data, int | np.integer)

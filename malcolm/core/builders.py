"""Builders for the core's own typeids, registered with :mod:`.typeids`.

Each builder checks the structure it is given and names the path inside it
where something is wrong; importing this module registers them all.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from .alarm import Alarm
from .block import BLOCK_TYPEID, Block
from .errors import BadValueError
from .fields import Attribute, Field, Method, MethodLog
from .generator import PointGeneratorMeta
from .metas import (
    NT_SCALAR,
    NT_SCALAR_ARRAY,
    NT_TABLE,
    ArrayMeta,
    BlockMeta,
    BooleanArrayMeta,
    BooleanMeta,
    ChoiceArrayMeta,
    ChoiceMeta,
    MapMeta,
    Meta,
    MethodMeta,
    NumberArrayMeta,
    NumberMeta,
    StringArrayMeta,
    StringMeta,
    TableMeta,
)
from .timestamp import TimeStamp
from .typeids import Builder, Path, build, located, register_typeid
from .typeids import short as _short


def _get(
    d: Mapping[str, Any],
    key: str,
    kind: type | tuple[type, ...],
    default: Any,
    path: Path,
) -> Any:
    value = d.get(key, default)
    if not isinstance(value, kind):
        raise located((*path, key), f"expected {_kind(kind)}, got {_short(value)}")
    return value


def _kind(kind: type | tuple[type, ...]) -> str:
    kinds = kind if isinstance(kind, tuple) else (kind,)
    names = {str: "a string", bool: "a boolean", list: "a list", Mapping: "a structure"}
    return " or ".join(names.get(k, k.__name__) for k in kinds)


def _strings(d: Mapping[str, Any], key: str, path: Path) -> list[str]:
    value = _get(d, key, (list, tuple), [], path)
    if not all(isinstance(v, str) for v in value):
        raise located((*path, key), f"expected strings, got {_short(value)}")
    return list(value)


def _common(
    d: Mapping[str, Any], path: Path, writeable: bool = False
) -> dict[str, Any]:
    return {
        "description": _get(d, "description", str, "", path),
        "tags": _strings(d, "tags", path),
        "writeable": _get(d, "writeable", bool, writeable, path),
        "label": _get(d, "label", str, "", path),
    }


def _number_meta(d: Mapping[str, Any], path: Path, name: str) -> NumberMeta:
    display = dict(_get(d, "display", Mapping, {}, path))
    display.pop("typeid", None)
    return NumberMeta(
        _get(d, "dtype", str, "float64", path), display=display, **_common(d, path)
    )


def _number_array_meta(d: Mapping[str, Any], path: Path, name: str) -> Meta:
    display = dict(_get(d, "display", Mapping, {}, path))
    display.pop("typeid", None)
    return NumberArrayMeta(
        _get(d, "dtype", str, "float64", path), display=display, **_common(d, path)
    )


def _simple(cls: type[Meta]) -> Builder:
    def builder(d: Mapping[str, Any], path: Path, name: str) -> Meta:
        return cls(**_common(d, path))

    return builder


def _with_choices(cls: type[ChoiceMeta] | type[ChoiceArrayMeta]) -> Builder:
    def builder(d: Mapping[str, Any], path: Path, name: str) -> Meta:
        return cls(_strings(d, "choices", path), **_common(d, path))

    return builder


def _elements(d: Mapping[str, Any], path: Path) -> dict[str, Meta]:
    elements = _get(d, "elements", Mapping, {}, path)
    out = {}
    for k, v in elements.items():
        meta = build(v, (*path, "elements", k))
        if not isinstance(meta, Meta):
            raise located(
                (*path, "elements", k), f"expected a meta, got {_short(meta)}"
            )
        out[k] = meta
    return out


def _table_meta(d: Mapping[str, Any], path: Path, name: str) -> TableMeta:
    elements = _elements(d, path)
    for k, meta in elements.items():
        if not isinstance(meta, ArrayMeta):
            raise located(
                (*path, "elements", k),
                f"a table column needs an array meta, not {meta.typeid}",
            )
    return TableMeta(elements, **_common(d, path))  # type: ignore[arg-type]


def _map_meta(d: Mapping[str, Any], path: Path, name: str) -> MapMeta:
    elements = _elements(d, path)
    required = _strings(d, "required", path)
    for r in required:
        if r not in elements:
            raise located((*path, "required"), f"{r!r} is not one of the elements")
    return MapMeta(elements, required, _get(d, "description", str, "", path))


def _sub_map(d: Mapping[str, Any], key: str, path: Path) -> MapMeta:
    if key not in d:
        return MapMeta()
    meta = build(d[key], (*path, key))
    if not isinstance(meta, MapMeta):
        raise located((*path, key), f"expected a MapMeta, got {meta!r}")
    return meta


def _method_meta(d: Mapping[str, Any], path: Path, name: str) -> MethodMeta:
    common = _common(d, path, writeable=True)
    takes = _sub_map(d, "takes", path)
    defaults = dict(_get(d, "defaults", Mapping, {}, path))
    for k in defaults:
        if k not in takes.elements:
            raise located(
                (*path, "defaults"), f"{k!r} is not one of the takes elements"
            )
    return MethodMeta(takes, _sub_map(d, "returns", path), defaults, **common)


def _block_meta(d: Mapping[str, Any], path: Path, name: str) -> BlockMeta:
    common = _common(d, path, writeable=True)
    return BlockMeta(fields=_strings(d, "fields", path), **common)


def _alarm(d: Mapping[str, Any], path: Path, name: str) -> Alarm:
    return Alarm.from_dict(d)


def _time_stamp(d: Mapping[str, Any], path: Path, name: str) -> TimeStamp:
    return TimeStamp.from_dict(d)


def _method_log(d: Mapping[str, Any], path: Path, name: str) -> MethodLog:
    _get(d, "value", Mapping, {}, path)
    _strings(d, "present", path)
    return MethodLog.from_dict(d)


def _typed(d: Mapping[str, Any], key: str, path: Path, cls: type) -> Any:
    """The object at ``d[key]``, checked to be a ``cls`` (the typeid is optional)."""
    value = d.get(key, {})
    if isinstance(value, Mapping) and "typeid" not in value:
        value = {**value, "typeid": cls.typeid}
    obj = build(value, (*path, key))
    if not isinstance(obj, cls):
        raise located((*path, key), f"expected {cls.typeid}")
    return obj


def _attribute(d: Mapping[str, Any], path: Path, name: str) -> Attribute:
    if "meta" not in d:
        raise located(path, "an attribute needs a meta")
    meta = build(d["meta"], (*path, "meta"))
    if not isinstance(meta, Meta) or isinstance(meta, MapMeta | MethodMeta | BlockMeta):
        raise located((*path, "meta"), f"not an attribute meta: {meta!r}")
    if meta.nt_typeid != d["typeid"]:
        raise located(path, f"{d['typeid']} does not fit a {meta.typeid} meta")
    value = d.get("value")
    if isinstance(meta, TableMeta) and isinstance(value, Mapping):
        value = {k: v for k, v in value.items() if k != "typeid"}
    try:
        value = meta.validate(value)
    except BadValueError as e:
        raise located((*path, "value"), str(e)) from None
    return Attribute(
        name or (path[-1] if path else ""),
        meta,
        value,
        alarm=_typed(d, "alarm", path, Alarm),
        timeStamp=_typed(d, "timeStamp", path, TimeStamp),
    )


def _method(d: Mapping[str, Any], path: Path, name: str) -> Method:
    if "meta" not in d:
        raise located(path, "a method needs a meta")
    meta = build(d["meta"], (*path, "meta"))
    if not isinstance(meta, MethodMeta):
        raise located((*path, "meta"), f"expected a MethodMeta: {meta!r}")
    method = Method(name or (path[-1] if path else ""), meta)
    method.took = _typed(d, "took", path, MethodLog)
    method.returned = _typed(d, "returned", path, MethodLog)
    return method


def _block(d: Mapping[str, Any], path: Path, name: str) -> Block:
    meta = _typed(d, "meta", path, BlockMeta)
    block = Block(name, meta.description, meta.tags)
    block.meta.writeable = meta.writeable
    block.meta.label = meta.label
    names = [k for k in d if k not in ("typeid", "meta")]
    if meta.fields != names:
        raise located(
            (*path, "meta", "fields"),
            f"lists {meta.fields} but the block has fields {names}",
        )
    for k in names:
        fld = build(d[k], (*path, k), k)
        if not isinstance(fld, Field):
            raise located((*path, k), f"expected an attribute or method, got {fld!r}")
        try:
            block.add(fld)
        except ValueError as e:
            raise located((*path, k), str(e)) from None
    return block


for _typeid, _builder in {
    NumberMeta.typeid: _number_meta,
    StringMeta.typeid: _simple(StringMeta),
    BooleanMeta.typeid: _simple(BooleanMeta),
    ChoiceMeta.typeid: _with_choices(ChoiceMeta),
    NumberArrayMeta.typeid: _number_array_meta,
    StringArrayMeta.typeid: _simple(StringArrayMeta),
    BooleanArrayMeta.typeid: _simple(BooleanArrayMeta),
    ChoiceArrayMeta.typeid: _with_choices(ChoiceArrayMeta),
    TableMeta.typeid: _table_meta,
    MapMeta.typeid: _map_meta,
    MethodMeta.typeid: _method_meta,
    BlockMeta.typeid: _block_meta,
    Alarm.typeid: _alarm,
    TimeStamp.typeid: _time_stamp,
    MethodLog.typeid: _method_log,
    NT_SCALAR: _attribute,
    NT_SCALAR_ARRAY: _attribute,
    NT_TABLE: _attribute,
    Method.typeid: _method,
    BLOCK_TYPEID: _block,
    PointGeneratorMeta.typeid: _simple(PointGeneratorMeta),
}.items():
    register_typeid(_typeid, _builder)

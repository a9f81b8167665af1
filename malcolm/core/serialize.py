"""From the Malcolm structure (plain data) back to objects, and client deltas.

``to_dict(obj)`` turns a block, field, meta, alarm or timeStamp into the plain
data of the Malcolm structure (interop.md §2); ``from_dict(d)`` rebuilds the
object by the structure's ``typeid``, through a registry that other modules
may extend with ``register_typeid``. ``apply_changes`` applies a list of
delta changes (interop.md §3) to plain data, as a client does.
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from .alarm import Alarm
from .block import BLOCK_TYPEID, Block
from .errors import BadValueError, NotFoundError
from .fields import Attribute, Field, Method, MethodLog
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
    plain,
)
from .timestamp import TimeStamp

Path = tuple[str, ...]
#: A builder gets the structure, where it is (for messages) and, for a field,
#: its name; it returns the object. Raise located(path, message).
Builder = Callable[[Mapping[str, Any], Path, str], Any]

_REGISTRY: dict[str, Builder] = {}


def where(path: Path, message: str) -> str:
    """``"counter.meta: message"``, or ``"top level: message"``."""
    return f"{'.'.join(path) or 'top level'}: {message}"


class _Located(BadValueError):
    """A BadValueError whose message already names its path."""


def located(path: Path, message: str) -> BadValueError:
    """The error a builder raises for a problem at ``path``."""
    return _Located(where(path, message))


def register_typeid(
    typeid: str, builder: Builder | None = None, replace: bool = False
) -> Any:
    """Register how to build the object for ``typeid``.

    Use as ``register_typeid(typeid, builder)`` or as a decorator
    ``@register_typeid(typeid)``. Registering a typeid twice is an error
    unless ``replace`` is true.
    """

    def register(func: Builder) -> Builder:
        if typeid in _REGISTRY and not replace and _REGISTRY[typeid] is not func:
            raise ValueError(f"typeid {typeid!r} is already registered")
        _REGISTRY[typeid] = func
        return func

    if builder is None:
        return register
    return register(builder)


def registered_typeids() -> list[str]:
    return list(_REGISTRY)


def from_dict(d: Mapping[str, Any], name: str = "") -> Any:
    """Rebuild the object a Malcolm structure describes, by its ``typeid``.

    ``name`` names the result where the structure does not: the mri of a
    block, the name of an attribute or method. Raises BadValueError naming
    the path inside ``d`` where something is wrong.
    """
    try:
        return build(d, (), name)
    except _Located as e:
        raise BadValueError(str(e)) from None


def build(d: Any, path: Path, name: str = "") -> Any:
    """``from_dict`` for the structure at ``path`` (for use by builders).

    Errors a builder raises without a path (e.g. from a constructor) are
    given this structure's path.
    """
    if not isinstance(d, Mapping):
        raise located(path, f"expected a structure, got {_short(d)}")
    typeid = d.get("typeid")
    if typeid is None:
        raise located(path, "the structure has no typeid")
    builder = _REGISTRY.get(typeid)
    if builder is None:
        raise located(path, f"unknown typeid {typeid!r}")
    try:
        return builder(d, path, name)
    except _Located:
        raise
    except BadValueError as e:
        raise located(path, str(e)) from None
    except (TypeError, ValueError, KeyError) as e:
        raise located(path, f"{type(e).__name__}: {e}") from None


def to_dict(obj: Any) -> Any:
    """The plain data of ``obj``: its ``to_dict()``, or containers of those."""
    if hasattr(obj, "to_dict"):
        return obj.to_dict()
    if isinstance(obj, Mapping):
        return {k: to_dict(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [to_dict(v) for v in obj]
    return plain(obj)


# ---- client side: applying deltas


def apply_changes(data: Any, changes: Sequence[Sequence[Any]]) -> Any:
    """Apply delta ``changes`` to plain ``data`` and return the result.

    Each change is ``[path, value]`` (set the value at path, adding the last
    key if it is new) or ``[path]`` (delete it); ``[[], value]`` replaces the
    whole and ``[[]]`` deletes it (the result is then None). Dicts in
    ``data`` are changed in place; values are copied in, so that later
    changes never alter what the sender (or another subscriber) holds.
    """
    for change in changes:
        if not isinstance(change, Sequence) or len(change) not in (1, 2):
            raise BadValueError(f"a change is [path, value] or [path], got {change!r}")
        path = list(change[0])
        if not path:
            data = copy.deepcopy(change[1]) if len(change) == 2 else None
            continue
        parent = data
        for i, key in enumerate(path[:-1]):
            if not isinstance(parent, dict) or key not in parent:
                raise NotFoundError(
                    f"change {_dotted(path)}: no {_dotted(path[: i + 1])!r}"
                )
            parent = parent[key]
        if not isinstance(parent, dict):
            raise NotFoundError(
                f"change {_dotted(path)}: {_dotted(path[:-1])!r} is not a structure"
            )
        last = path[-1]
        if len(change) == 2:
            parent[last] = copy.deepcopy(change[1])
        elif last in parent:
            del parent[last]
        else:
            raise NotFoundError(f"change {_dotted(path)}: nothing to delete")
    return data


def _dotted(path: Sequence[Any]) -> str:
    return ".".join(map(str, path))


# ---- builders


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


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
}.items():
    register_typeid(_typeid, _builder)

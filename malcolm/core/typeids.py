"""The typeid registry: from the Malcolm structure (plain data) back to objects.

``to_dict(obj)`` turns a block, field, meta, alarm or timeStamp into the plain
data of the Malcolm structure (interop.md §2); ``from_dict(d)`` rebuilds the
object by the structure's ``typeid``, through a registry that other modules
extend with ``register_typeid`` (:mod:`malcolm.core.builders` registers the
core's own structures).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from .errors import BadValueError
from .metas import plain

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
        raise located(path, f"expected a structure, got {short(d)}")
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


def short(value: Any) -> str:
    """``repr(value)``, cut to 60 characters for messages."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."

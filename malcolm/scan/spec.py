"""Scan points from a scanspec 1.x `Spec` or its serialized dict.

The spec's `calculate()` gives the stack of dimensions (outer -> inner; a
`SnakedDimension` is a snake), each holding its own points; they are kept as
they are (`ArrayDimension`) and a scan step's points are taken from them as
scanspec's `Path` would. Bounds are only different from positions where the
spec flies (`Fly`), and duration is only present where the spec sets one
(`ConstantDuration`, ``duration @ spec``).

scanspec is imported only here, and only when a Spec is used: importing it
builds its pydantic schemas, which takes half a second.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Mapping
from typing import Any

import numpy as np

from .dimensions import ArrayDimension
from .errors import GeneratorError
from .fields import describe, join
from .generators import check_size
from .points import ScanPoints


def is_spec(value: Any) -> bool:
    """Whether ``value`` is a scanspec Spec, without importing scanspec: if it
    was never imported, nothing can be one."""
    specs = sys.modules.get("scanspec.specs")
    return specs is not None and isinstance(value, specs.Spec)


def _axis_name(axis: Any) -> str:
    """scanspec axes may be any object: use a str, or the object's name."""
    if isinstance(axis, str):
        return axis
    name = getattr(axis, "name", None)
    return name if isinstance(name, str) else repr(axis)


def _error_path(data: Any, loc: tuple[Any, ...], path: str) -> str:
    """Turn a pydantic error location into a path within ``data``, skipping the
    union tags pydantic adds (they are not keys of the input)."""
    obj = data
    for part in loc:
        if isinstance(obj, Mapping) and part in obj:
            path, obj = join(path, str(part)), obj[part]
        elif isinstance(obj, list) and isinstance(part, int) and part < len(obj):
            path, obj = join(path, part), obj[part]
    return path


def deserialize_spec(data: Mapping[str, Any], path: str = "") -> Any:
    """Build a Spec from what ``Spec.serialize()`` gives.

    Raises:
        GeneratorError: naming where in ``data`` the first problem is.
    """
    from pydantic import ValidationError
    from scanspec.specs import Spec

    try:
        return Spec.deserialize(data)
    except ValidationError as e:
        errors = e.errors()
        first = errors[0]
        where = _error_path(data, tuple(first.get("loc", ())), path)
        message = first.get("msg", "invalid")
        if first.get("type") == "union_tag_invalid":
            where = join(where, "type")
        elif "input" in first and not isinstance(first["input"], Mapping | list):
            message += f", got {describe(first['input'])}"
        raise GeneratorError(where, message) from None
    except Exception as e:  # raised by a Spec's own checks while building it
        raise GeneratorError(path, f"invalid scanspec Spec: {e}") from None


def _floats(source: Mapping[Any, Any], originals: list[Any]) -> dict[str, np.ndarray]:
    return {_axis_name(a): np.asarray(source[a], dtype=float) for a in originals}


def spec_points(spec: Any, path: str = "") -> ScanPoints:
    """The scan points of a scanspec Spec: its dimensions as scanspec
    calculates them (each of its own size), the scan's steps computed when
    asked for.

    Raises:
        GeneratorError: if scanspec cannot calculate the scan, it is too big,
            or its numbers are not finite.
    """
    from scanspec.core import SnakedDimension

    where = path
    try:
        stack = spec.calculate()
        shape = [len(dim) for dim in stack]
        check_size(math.prod(shape), where)
    except GeneratorError:
        raise
    except Exception as e:  # scanspec raises many kinds for bad parameters
        raise GeneratorError(where, f"cannot calculate the scan: {e}") from None

    originals = [a for dim in stack for a in dim.axes()]
    axes = [_axis_name(a) for a in originals]
    if len(set(axes)) != len(axes):
        raise GeneratorError(where, f"axis names are not unique: {axes}")
    if sum(dim.duration is not None for dim in stack) > 1:
        # what scanspec's Path says when it meets such a stack
        raise GeneratorError(
            where, "cannot calculate the scan: Can't have more than one durations array"
        )

    dimensions = []
    for dim, size in zip(stack, shape):
        mine = dim.axes()
        durations = None
        if dim.duration is not None:
            durations = np.asarray(dim.duration, dtype=float)
        positions = _floats(dim.midpoints, mine)
        dimension = ArrayDimension(
            [_axis_name(a) for a in mine],
            positions,
            positions if dim.lower is dim.midpoints else _floats(dim.lower, mine),
            positions if dim.upper is dim.midpoints else _floats(dim.upper, mine),
            isinstance(dim, SnakedDimension),
            size,
            durations,
        )
        for name in ("positions", "lower", "upper"):
            for axis, values in getattr(dimension, name).items():
                if not np.all(np.isfinite(values)):
                    raise GeneratorError(
                        where,
                        f"{name} of axis {axis!r} are not all finite "
                        "(inputs too large?)",
                    )
        if durations is not None and not np.all(np.isfinite(durations)):
            raise GeneratorError(where, "durations are not all finite")
        dimensions.append(dimension)
    return ScanPoints(dimensions)

"""Scan points from a scanspec 1.x `Spec` or its serialized dict.

The spec's `calculate()` gives the stack of dimensions (outer -> inner; a
`SnakedDimension` is a snake), and a `Path` through the stack gives every
point. Bounds are only different from positions where the spec flies (`Fly`),
and duration is only present where the spec sets one (`ConstantDuration`,
``duration @ spec``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from pydantic import ValidationError
from scanspec.core import Path, SnakedDimension
from scanspec.specs import Spec

from .errors import GeneratorError
from .fields import describe, join
from .generators import check_size
from .points import Dimension, ScanPoints


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


def deserialize_spec(data: Mapping[str, Any], path: str = "") -> Spec[Any]:
    """Build a Spec from what ``Spec.serialize()`` gives.

    Raises:
        GeneratorError: naming where in ``data`` the first problem is.
    """
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


def spec_points(spec: Spec[Any], path: str = "") -> ScanPoints:
    """Compute the scan points of a scanspec Spec.

    Raises:
        GeneratorError: if scanspec cannot calculate the scan or it is too big.
    """
    where = path
    try:
        stack = spec.calculate()
        shape = [len(dim) for dim in stack]
        check_size(math.prod(shape), where)
        frames = Path(stack).consume()
    except GeneratorError:
        raise
    except Exception as e:  # scanspec raises many kinds for bad parameters
        raise GeneratorError(where, f"cannot calculate the scan: {e}") from None

    dimensions = [
        Dimension(
            [_axis_name(a) for a in dim.axes()],
            len(dim),
            isinstance(dim, SnakedDimension),
        )
        for dim in stack
    ]
    originals = [a for dim in stack for a in dim.axes()]
    axes = [_axis_name(a) for a in originals]
    if len(set(axes)) != len(axes):
        raise GeneratorError(where, f"axis names are not unique: {axes}")

    def arrays(source: Mapping[Any, np.ndarray]) -> dict[str, np.ndarray]:
        return {
            name: np.asarray(source[a], dtype=float) for name, a in zip(axes, originals)
        }

    duration = None
    if frames.duration is not None:
        duration = np.asarray(frames.duration, dtype=float)
    return ScanPoints(
        axes=axes,
        shape=shape,
        dimensions=dimensions,
        positions=arrays(frames.midpoints),
        lower=arrays(frames.lower),
        upper=arrays(frames.upper),
        duration=duration,
    )

"""What building a scan costs, estimated from its description without building it.

`scan_points` computes no point for most scans, so building one costs next to
nothing; the exceptions are where the work grows with the input:

- a region joining dimensions evaluates every point of the joined dimension
  (the product of the sizes of the generators from its outermost to its
  innermost axis) when the scan is built;
- a scanspec Spec (or its serialized dict) is ``calculate``-d, and importing
  scanspec takes half a second: always costly;
- big data (an explicit array of points, a polygon of many vertices) is read
  and checked an item at a time, in Python.

`build_cost` adds these up in one unit, points evaluated (an item of data
counts as `DATA_ITEM_COST` of them, about what reading and checking it costs
next to evaluating a point); `cheap_to_build` compares it with
`CHEAP_BUILD_COST`. Whatever is not understood (a typeid not known here, a
size a region needs that is not a number) is costly: the estimate errs on
the side of the worker thread. Estimating reads at most the first few
hundred items of the data, so it is cheap itself, and imports nothing (not
numpy).
"""

from __future__ import annotations

import math
import os
import sys
from collections.abc import Mapping, Sequence
from typing import Any

#: What reading and checking one item of data (a number in a list, a key of
#: a mapping) costs, in points evaluated
DATA_ITEM_COST = 20

#: Build cost at or below which a scan is cheap to build: about half a
#: millisecond of work here (a region over a 100 x 100 grid is not cheap)
CHEAP_BUILD_COST = 10_000

_COSTLY = math.inf

_GENERATOR = "scanpointgenerator:generator/"


def cheap_to_build(generator: Any, limit: float = CHEAP_BUILD_COST) -> bool:
    """Whether building ``generator`` (anything `scan_points` takes) costs at
    most ``limit`` (see `build_cost`), so it may be built where a
    millisecond matters (on the event loop)."""
    return build_cost(generator, limit) <= limit


def build_cost(generator: Any, limit: float = _COSTLY) -> float:
    """An estimate of the work `scan_points` does to build ``generator``, in
    points evaluated: its data items (each `DATA_ITEM_COST`) and the points
    its regions evaluate; ``inf`` for a scanspec Spec and for anything not
    understood. Counting stops once past ``limit`` (the result is then some
    value above it), so the estimate costs no more than the limit allows."""
    if type(generator) is not dict:  # a dict is the usual case
        if _is_scan_points(generator):
            return 0.0
        if isinstance(generator, str | bytes | os.PathLike):
            return 0.0  # refused before anything is read
    items = _count_items(generator, limit / DATA_ITEM_COST)
    cost = items * DATA_ITEM_COST
    if cost > limit:
        return cost
    if not isinstance(generator, Mapping | list | tuple):
        return _COSTLY  # a Spec object, or something scan_points will judge
    if (
        isinstance(generator, Mapping)
        and set(generator) == {"generator"}
        and isinstance(generator["generator"], Mapping)
    ):
        generator = generator["generator"]
    if not isinstance(generator, Mapping):
        return cost  # refused as soon as it is looked at
    if "type" in generator and "typeid" not in generator:
        return _COSTLY  # a serialized scanspec Spec: calculate()
    try:
        return cost + _evaluated(generator)
    except (TypeError, ValueError, KeyError, ZeroDivisionError, OverflowError):
        return _COSTLY


def _is_scan_points(value: Any) -> bool:
    points = sys.modules.get("malcolm.scan.points")
    return points is not None and isinstance(value, points.ScanPoints)


#: Types of the plain values in data: nothing inside them to count
_SCALARS = frozenset({str, int, float, bool, type(None)})


def _count_items(data: Any, limit: float) -> int:
    """Mapping entries and list elements in ``data``, all levels, counting
    no further once past ``limit``."""
    count = 0
    stack = [data]
    push, pop = stack.append, stack.pop
    while stack:
        value = pop()
        kind = type(value)
        if kind is dict:  # the usual case, and the fastest check
            values: Any = value.values()
        elif kind is list or kind is tuple:
            values = value
        elif isinstance(value, Mapping):
            values = value.values()
        elif isinstance(value, list | tuple):
            values = value
        else:
            continue  # a number, text, or something scan_points will judge
        count += len(values)
        if count > limit:  # the rest is not looked at
            break
        for item in values:
            if type(item) not in _SCALARS:
                push(item)
    return count


def _kind(data: Any) -> str:
    """``LineGenerator`` of ``scanpointgenerator:generator/LineGenerator:1.0``."""
    typeid = data["typeid"]
    if not isinstance(typeid, str) or not typeid.startswith(_GENERATOR):
        raise ValueError(typeid)
    return typeid[len(_GENERATOR) :].split(":")[0]


def _number(value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise TypeError(value)
    return float(value)


def _children(data: Mapping[str, Any]) -> list[Mapping[str, Any]]:
    children = data["generators"]
    if not isinstance(children, list) or not children:
        raise ValueError(children)
    return children


def _size(data: Mapping[str, Any]) -> float:
    """The number of points of one generator dict."""
    kind = _kind(data)
    if kind in ("LineGenerator", "StaticPointGenerator", "StaticGenerator"):
        return _number(data["size"])
    if kind == "LissajousGenerator":
        if "size" in data:
            return _number(data["size"])
        return 250 * _number(data["lobes"])
    if kind == "SpiralGenerator":
        # rings = radius / (sqrt(4 pi) * scale / (2 pi)); size = rings ** 2 + 1
        scale = _number(data.get("scale", 1.0))
        rings = _number(data["radius"]) * math.sqrt(math.pi) / scale
        return rings * rings + 1
    if kind == "ArrayGenerator":
        return float(len(data["points"]))
    if kind == "ZipGenerator":
        return max(_size(g) for g in _children(data))
    if kind == "ConcatGenerator":
        return sum(_size(g) for g in _children(data))
    raise ValueError(kind)


def _axes(data: Mapping[str, Any]) -> list[str]:
    """The axes one generator dict moves."""
    kind = _kind(data)
    if kind == "ZipGenerator":
        return [a for g in _children(data) for a in _axes(g)]
    if kind == "ConcatGenerator":
        return _axes(_children(data)[0])
    axes = data.get("axes", data.get("axis", []))
    axes = [axes] if isinstance(axes, str) else axes
    if not isinstance(axes, Sequence):
        raise TypeError(axes)
    return list(axes)


def _evaluated(data: Mapping[str, Any]) -> float:
    """Points a CompoundGenerator dict's build evaluates: each region's joined
    dimension (counted whole, even where a rectangle only shortens two
    lines), and every point of an explicit array (checked to be finite)."""
    generators = data["generators"]
    excluders = data.get("excluders") or []
    if not isinstance(generators, list) or not isinstance(excluders, list):
        raise TypeError("generators")
    points = sum(_explicit(g) for g in generators)
    if not excluders:
        return points
    sizes = [_size(g) for g in generators]
    owners = {axis: i for i, g in enumerate(generators) for axis in _axes(g)}
    for excluder in excluders:
        spanned = [owners[axis] for axis in excluder["axes"]]
        points += math.prod(sizes[min(spanned) : max(spanned) + 1])
    return points


#: The generators whose build evaluates none of their points
_FORMULAS = frozenset(
    {
        "LineGenerator",
        "SpiralGenerator",
        "LissajousGenerator",
        "StaticPointGenerator",
        "StaticGenerator",
    }
)


def _explicit(data: Mapping[str, Any]) -> float:
    """Points given explicitly in one generator dict (an array's); a kind
    not known here raises (so it counts as costly)."""
    kind = _kind(data)
    if kind in _FORMULAS:
        return 0.0
    if kind == "ArrayGenerator":
        return float(len(data["points"]))
    if kind in ("ZipGenerator", "ConcatGenerator"):
        return sum(_explicit(g) for g in _children(data))
    raise ValueError(kind)

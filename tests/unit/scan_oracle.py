"""The eager algorithm malcolm used before scan points were computed lazily,
kept as the oracle the lazy one must equal exactly: every generator's points
expanded whole, each dimension unrolled and masked whole, then the whole scan
expanded at once. Memory grows with the product of the dimensions' sizes, so
only small scans are given to it.

It shares the parsing of generator dicts with `malcolm.scan` (parse, merge of
dimensions by regions) and the per-index formulas of each curve, but none of
the composition: zips, concats, snakes, regions, rectangles and the final
expansion are done here as they were.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from malcolm.scan.compound import _Dim, _merge_dimensions, _reject_mutator
from malcolm.scan.errors import GeneratorError
from malcolm.scan.fields import Fields
from malcolm.scan.generators import (
    COMPOUND_TYPEID,
    CurveGenerator,
    Generator,
    LineGenerator,
    StaticGenerator,
    check_size,
)
from malcolm.scan.nested import ConcatGenerator, ZipGenerator, parse_generator
from malcolm.scan.regions import Excluder, parse_excluder
from malcolm.scan.rois import RectangularROI

Arrays = dict[str, np.ndarray]


def full_positions(gen: Generator) -> Arrays:
    """Every position of ``gen``, as the eager code computed them."""
    if isinstance(gen, ZipGenerator):
        return {k: v for g in gen.generators for k, v in full_positions(g).items()}
    if isinstance(gen, ConcatGenerator):
        parts = [full_positions(g) for g in gen.generators]
        return {a: np.concatenate([p[a] for p in parts]) for a in gen.axes}
    if isinstance(gen, StaticGenerator):
        return {a: np.arange(1, gen.size + 1, dtype=float) for a in gen.axes}
    assert isinstance(gen, CurveGenerator)
    return gen._arrays(np.arange(gen.size, dtype=float))


def full_bounds(gen: Generator) -> Arrays:
    """Every bound of ``gen``, as the eager code computed them."""
    if isinstance(gen, ZipGenerator):
        return {k: v for g in gen.generators for k, v in full_bounds(g).items()}
    if isinstance(gen, ConcatGenerator):
        parts = [full_bounds(g) for g in gen.generators]
        result = {}
        for axis in gen.axes:
            pieces = [parts[0][axis]]
            for child, part in zip(gen.generators[1:], parts[1:]):
                end, begin = float(pieces[-1][-1]), float(part[axis][0])
                if abs(end - begin) >= gen.BOUNDS_TOLERANCE:
                    raise GeneratorError(
                        child.path,
                        f"bounds of axis {axis!r} do not join the previous "
                        f"generator's ({begin:g} != {end:g}); a continuous scan "
                        f"needs them to meet (or set continuous to false)",
                    )
                pieces[-1] = pieces[-1][:-1]
                pieces.append(part[axis])
            result[axis] = np.concatenate(pieces)
        return result
    if isinstance(gen, StaticGenerator):
        return {a: np.arange(1, gen.size + 2, dtype=float) for a in gen.axes}
    assert isinstance(gen, CurveGenerator)
    return gen._arrays(np.arange(gen.size + 1, dtype=float) - 0.5)


def _shrink(generators: list[Generator], excluder: Excluder) -> list[Generator] | None:
    if len(excluder.rois) != 1:
        return None
    rect = excluder.rois[0]
    if not isinstance(rect, RectangularROI) or rect.angle != 0:
        return None
    owners = []
    for axis in excluder.axes:
        owner = [g for g in generators if axis in g.axes]
        if not owner:
            raise GeneratorError(
                excluder.path + ".axes",
                f"axis {axis!r} is not scanned by any generator",
            )
        owners.append(owner[0])
    if owners[0] is owners[1] or not all(isinstance(g, LineGenerator) for g in owners):
        return None
    limits = [
        (rect.start[0], rect.start[0] + rect.width),
        (rect.start[1], rect.start[1] + rect.height),
    ]
    result = list(generators)
    for axis, gen, (low, high) in zip(excluder.axes, owners, limits):
        positions = full_positions(gen)
        inside = np.flatnonzero((positions[axis] >= low) & (positions[axis] <= high))
        if len(inside) == 0:
            raise GeneratorError(
                excluder.path,
                f"region excludes every point of axis {axis!r}, so the whole scan",
            )
        first, last = inside[0], inside[-1]
        result[result.index(gen)] = LineGenerator(
            gen.path,
            gen.axes,
            gen.units,
            [float(positions[a][first]) for a in gen.axes],
            [float(positions[a][last]) for a in gen.axes],
            len(inside),
            gen.alternate,
        )
    return result


def _prepare(dim: _Dim, bounded: Generator | None, path: str) -> dict[str, Any]:
    full = math.prod(g.size for g in dim.generators)
    check_size(full, path)
    t = np.arange(full)
    positions: Arrays = {}
    lower: Arrays = {}
    upper: Arrays = {}
    after = full
    for gen in dim.generators:
        after //= gen.size
        runs = t // (after * gen.size)
        index = (t // after) % gen.size
        backwards = gen.alternate & (runs % 2 == 1)
        index = np.where(backwards, gen.size - 1 - index, index)
        gen_positions = full_positions(gen)
        for axis in gen.axes:
            positions[axis] = np.asarray(gen_positions[axis], dtype=float)[index]
        if gen is bounded:
            gen_bounds = full_bounds(gen)
            step = backwards.astype(int)
            for axis in gen.axes:
                b = np.asarray(gen_bounds[axis], dtype=float)
                lower[axis] = b[index + step]
                upper[axis] = b[index + 1 - step]
    keep = np.ones(full, dtype=bool)
    for excluder in dim.excluders:
        keep &= excluder.mask(positions)
    indices = np.flatnonzero(keep)
    if len(indices) == 0:
        raise GeneratorError(path, "regions would exclude the entire scan")
    kept = {a: v[indices] for a, v in positions.items()}
    return {
        "axes": dim.axes,
        "alternate": dim.generators[0].alternate,
        "size": len(indices),
        "positions": kept,
        "lower": {a: lower[a][indices] if a in lower else kept[a] for a in kept},
        "upper": {a: upper[a][indices] if a in upper else kept[a] for a in kept},
    }


def oracle_points(data: dict[str, Any]) -> dict[str, Any]:
    """Every point of a CompoundGenerator dict, computed eagerly.

    Returns a dict with ``axes``, ``shape``, ``dimensions`` (tuples of axes,
    size, snake), per-axis ``positions``, ``lower``, ``upper`` arrays and
    ``duration`` (an array or None). Raises GeneratorError as malcolm did.
    """
    with np.errstate(all="ignore"):
        return _oracle(data)


def _oracle(data: dict[str, Any]) -> dict[str, Any]:
    fields = Fields(data, "")
    typeid = fields.string("typeid")
    if typeid != COMPOUND_TYPEID:
        raise GeneratorError("typeid", f"expected {COMPOUND_TYPEID!r}, got {typeid!r}")
    items = fields.items("generators")
    if not items:
        raise GeneratorError("generators", "expected at least one generator")
    generators = [parse_generator(value, path) for path, value in items]
    excluders = [parse_excluder(v, p) for p, v in fields.items("excluders", [])]
    for path, value in fields.items("mutators", []):
        _reject_mutator(value, path)
    duration: float | None = fields.number("duration", default=-1.0)
    continuous = fields.boolean("continuous", default=True)
    fields.number("delay_after", default=0.0)
    fields.check_no_extra()
    seen: dict[str, str] = {}
    for gen in generators:
        for axis in gen.axes:
            if axis in seen:
                raise GeneratorError(
                    gen.path, f"axis {axis!r} is already used by {seen[axis]}"
                )
            seen[axis] = gen.path
    if duration is not None and duration < 0:
        duration = None
    remaining = []
    for excluder in excluders:
        shrunk = _shrink(generators, excluder)
        if shrunk is None:
            remaining.append(excluder)
        else:
            generators = shrunk
    dims = [_Dim([g], []) for g in generators]
    for excluder in remaining:
        dims = _merge_dimensions(dims, excluder)
    bounded = generators[-1] if continuous else None
    prepared = [
        _prepare(
            dim,
            bounded if i == len(dims) - 1 else None,
            dim.excluders[-1].path if dim.excluders else dim.generators[0].path,
        )
        for i, dim in enumerate(dims)
    ]
    sizes = [d["size"] for d in prepared]
    total = math.prod(sizes)
    check_size(total, "generators")
    n = np.arange(total)
    positions: Arrays = {}
    lower: Arrays = {}
    upper: Arrays = {}
    repeat = total
    for i, dim in enumerate(prepared):
        size = dim["size"]
        repeat //= size
        k = n // repeat
        index = k % size
        backwards = dim["alternate"] & ((k // size) % 2 == 1)
        index = np.where(backwards, size - 1 - index, index)
        for axis in dim["axes"]:
            positions[axis] = dim["positions"][axis][index]
            if i == len(prepared) - 1:
                lower[axis] = np.where(
                    backwards, dim["upper"][axis][index], dim["lower"][axis][index]
                )
                upper[axis] = np.where(
                    backwards, dim["lower"][axis][index], dim["upper"][axis][index]
                )
            else:
                lower[axis] = upper[axis] = positions[axis]
    axes = [a for g in generators for a in g.axes]
    for name, arrays in (("positions", positions), ("lower", lower), ("upper", upper)):
        for axis, values in arrays.items():
            if not np.all(np.isfinite(values)):
                raise GeneratorError(
                    "",
                    f"{name} of axis {axis!r} are not all finite (inputs too large?)",
                )
    return {
        "axes": axes,
        "shape": sizes,
        "dimensions": [(list(d["axes"]), d["size"], d["alternate"]) for d in prepared],
        "positions": {a: positions[a] for a in axes},
        "lower": {a: lower[a] for a in axes},
        "upper": {a: upper[a] for a in axes},
        "duration": None if duration is None else np.full(total, duration),
    }

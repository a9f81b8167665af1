"""Scan points from a scanpointgenerator CompoundGenerator dict.

This reproduces the points scanpointgenerator 3.x produces:

- Generators are nested outer -> inner; each starts as its own dimension.
- An ROIExcluder holding a single unrotated RectangularROI whose two axes
  belong to two different LineGenerators does not mask anything: it shrinks
  both lines to the points inside the rectangle (which keeps the scan a grid,
  so the shape stays N-dimensional and a snake restarts forwards).
- Any other excluder merges the dimensions from its outermost to its
  innermost axis into one dimension, unrolls that dimension's points (snaking
  alternate generators within it) and keeps the points inside any of its ROIs.
- A dimension whose first generator alternates runs backwards on every odd
  pass of the dimensions outside it.
- Only the innermost generator has real bounds (and only if ``continuous``);
  every other axis has lower == upper == position. Running backwards swaps
  lower and upper.

Nothing here computes the scan's points: each dimension is a
`GeneratorDimension` that computes its own when asked. The one exception is a
dimension with a region, whose kept points are found once, a chunk at a time
(`malcolm.scan.regions`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from .dimensions import GeneratorDimension
from .errors import GeneratorError
from .fields import Fields
from .generators import COMPOUND_TYPEID, Generator, LineGenerator, check_size
from .nested import parse_generator
from .points import ScanPoints
from .regions import CHUNK, Excluder, find_runs, parse_excluder
from .rois import RectangularROI

#: scanpointgenerator's mutators (its only one in 3.1), which we do not reproduce
UNSUPPORTED_MUTATORS = {
    "scanpointgenerator:mutator/RandomOffsetMutator:1.0": "RandomOffsetMutator",
}


def _reject_mutator(data: Any, path: str) -> None:
    """Mutators change points after they are generated; none is supported."""
    typeid = Fields(data, path).string("typeid")
    if typeid in UNSUPPORTED_MUTATORS:
        raise GeneratorError(
            path,
            f"{UNSUPPORTED_MUTATORS[typeid]} is not supported "
            "(mutators must be an empty list)",
        )
    raise GeneratorError(path, f"unknown typeid {typeid!r}")


@dataclass
class _Dim:
    """One dimension of the scan: generators merged by excluders."""

    generators: list[Generator]
    excluders: list[Excluder]

    @property
    def axes(self) -> list[str]:
        return [a for g in self.generators for a in g.axes]

    @property
    def path(self) -> str:
        """What names the dimension in an error: its last excluder, or its
        generator."""
        return self.excluders[-1].path if self.excluders else self.generators[0].path


def _inside(gen: LineGenerator, axis: str, low: float, high: float) -> list[int]:
    """First and last index, and the number of points, of ``gen`` whose
    ``axis`` is within ``low .. high`` (empty if none), a chunk at a time."""
    first = last = -1
    count = 0
    for start in range(0, gen.size, CHUNK):
        index = np.arange(start, min(gen.size, start + CHUNK))
        values = gen.positions_at(index)[axis]
        inside = np.flatnonzero((values >= low) & (values <= high))
        if len(inside):
            first = int(index[inside[0]]) if first < 0 else first
            last = int(index[inside[-1]])
            count += len(inside)
    return [first, last, count] if count else []


def _shrink_to_rectangle(
    generators: list[Generator], excluder: Excluder
) -> list[Generator] | None:
    """Apply an unrotated rectangle on two LineGenerators by shortening them.

    Returns the new generator list, or None if this excluder does not qualify
    (then it is applied as a mask like any other).
    """
    if len(excluder.rois) != 1:
        return None
    rect = excluder.rois[0]
    if not isinstance(rect, RectangularROI) or rect.angle != 0:
        return None
    owners = [_owner(generators, axis, excluder) for axis in excluder.axes]
    if owners[0] is owners[1]:
        return None
    if not all(isinstance(g, LineGenerator) for g in owners):
        return None
    limits = [
        (rect.start[0], rect.start[0] + rect.width),
        (rect.start[1], rect.start[1] + rect.height),
    ]
    result = list(generators)
    for axis, gen, (low, high) in zip(excluder.axes, owners, limits):
        assert isinstance(gen, LineGenerator)
        inside = _inside(gen, axis, low, high)
        if not inside:
            raise GeneratorError(
                excluder.path,
                f"region excludes every point of axis {axis!r}, so the whole scan",
            )
        first, last, count = inside
        ends = gen.positions_at(np.array([first, last]))
        result[result.index(gen)] = LineGenerator(
            gen.path,
            gen.axes,
            gen.units,
            [float(ends[a][0]) for a in gen.axes],
            [float(ends[a][1]) for a in gen.axes],
            count,
            gen.alternate,
        )
    return result


def _owner(generators: list[Generator], axis: str, excluder: Excluder) -> Generator:
    for gen in generators:
        if axis in gen.axes:
            return gen
    raise GeneratorError(
        excluder.path + ".axes", f"axis {axis!r} is not scanned by any generator"
    )


def _merge_dimensions(dims: list[_Dim], excluder: Excluder) -> list[_Dim]:
    """Merge the dimensions the excluder's axes span and attach it there."""
    for axis in excluder.axes:
        if not any(axis in d.axes for d in dims):
            raise GeneratorError(
                excluder.path + ".axes",
                f"axis {axis!r} is not scanned by any generator",
            )
    hit = [i for i, d in enumerate(dims) if set(d.axes) & set(excluder.axes)]
    start, end = hit[0], hit[-1]
    merged = _Dim(
        [g for d in dims[start : end + 1] for g in d.generators],
        [e for d in dims[start : end + 1] for e in d.excluders] + [excluder],
    )
    alternating = None
    for gen in merged.generators:
        if alternating is not None and gen.alternate is False:
            raise GeneratorError(
                excluder.path,
                f"its region joins {alternating.path}, which alternates, with "
                f"{gen.path} inside it, which does not; a non-alternating "
                f"generator cannot be nested in an alternating one in a region",
            )
        if gen.alternate and alternating is None:
            alternating = gen
    return dims[:start] + [merged] + dims[end + 1 :]


def _build(dim: _Dim, bounded: Generator | None) -> GeneratorDimension:
    """The dimension's points: its generators unrolled (snaking within it),
    keeping only the points inside its excluders' regions, with ``bounded``
    (the scan's innermost generator, if it is in this dimension and the scan
    is continuous) giving real bounds."""
    check_size(math.prod(g.size for g in dim.generators), dim.path)
    if bounded is not None:
        bounded.check_bounds()
    unmasked = GeneratorDimension(dim.generators, bounded)
    if not dim.excluders:
        return unmasked
    axes = {a for e in dim.excluders for a in e.axes}

    def keep(unrolled: np.ndarray) -> np.ndarray:
        positions, _, _ = unmasked.unrolled(unrolled, axes, bounds=False)
        kept = np.ones(len(unrolled), dtype=bool)
        for excluder in dim.excluders:
            kept &= excluder.mask(positions)
        return kept

    runs = find_runs(unmasked.unrolled_size, keep)
    if runs.size == 0:
        raise GeneratorError(dim.path, "regions would exclude the entire scan")
    return GeneratorDimension(dim.generators, bounded, runs)


def _check_finite(generators: list[Generator], bounded: Generator | None) -> None:
    """Reject a scan whose numbers overflow (absurdly large inputs), from a
    few values per generator (`Generator.extremes`)."""
    for gen in generators:
        for path, axis, values in gen.extremes(bounds=gen is bounded):
            if isinstance(values, np.ndarray):
                finite = bool(np.all(np.isfinite(values)))
            else:  # a few Python floats (a line's)
                finite = all(math.isfinite(v) for v in values)
            if not finite:
                raise GeneratorError(
                    path,
                    f"positions or bounds of axis {axis!r} are not all finite "
                    "(inputs too large?)",
                )


def compound_points(data: Mapping[str, Any]) -> ScanPoints:
    """The scan points of a CompoundGenerator dict, computed when asked for.

    Raises:
        GeneratorError: naming the path of the first problem found in ``data``.
    """
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
    fields.number("delay_after", default=0.0)  # checked, but not a point property
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
        if duration != -1:  # issue 9: a negative duration is refused
            raise GeneratorError(
                "duration", f"expected at least 0 (or -1: none), got {duration}"
            )
        duration = None  # scanpointgenerator's -1: no fixed duration

    remaining = []
    for excluder in excluders:
        shrunk = _shrink_to_rectangle(generators, excluder)
        if shrunk is None:
            remaining.append(excluder)
        else:
            generators = shrunk

    dims = [_Dim([g], []) for g in generators]
    for excluder in remaining:
        dims = _merge_dimensions(dims, excluder)

    bounded = generators[-1] if continuous else None
    built = [
        _build(dim, bounded if i == len(dims) - 1 else None)
        for i, dim in enumerate(dims)
    ]
    check_size(math.prod(d.size for d in built), "generators")
    _check_finite(generators, bounded)
    return ScanPoints(built, duration)

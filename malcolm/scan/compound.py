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
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from .errors import GeneratorError
from .fields import Fields
from .generators import (
    COMPOUND_TYPEID,
    Arrays,
    Generator,
    LineGenerator,
    check_size,
    parse_generator,
)
from .points import Dimension, ScanPoints
from .rois import ROI, RectangularROI, parse_roi

ROI_EXCLUDER_TYPEID = "scanpointgenerator:excluder/ROIExcluder:1.0"
#: scanpointgenerator's mutators (its only one in 3.1), which we do not reproduce
UNSUPPORTED_MUTATORS = {
    "scanpointgenerator:mutator/RandomOffsetMutator:1.0": "RandomOffsetMutator",
}


@dataclass
class _Excluder:
    """A parsed ROIExcluder."""

    path: str
    axes: list[str]
    rois: list[ROI]

    def mask(self, positions: Arrays) -> np.ndarray:
        """True where a point is inside any of the ROIs."""
        x, y = positions[self.axes[0]], positions[self.axes[1]]
        inside = np.zeros(len(x), dtype=bool)
        for roi in self.rois:
            inside |= roi.mask(x, y)
        return inside


def _parse_excluder(data: Any, path: str) -> _Excluder:
    fields = Fields(data, path)
    typeid = fields.string("typeid")
    if typeid != ROI_EXCLUDER_TYPEID:
        raise GeneratorError(path, f"unknown typeid {typeid!r}")
    axes = fields.axes(count=2)
    items = fields.items("rois")
    if not items:
        raise GeneratorError(fields.at("rois"), "expected at least one ROI")
    rois = [parse_roi(value, roi_path) for roi_path, value in items]
    fields.check_no_extra()
    return _Excluder(path, axes, rois)


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
    excluders: list[_Excluder]

    @property
    def axes(self) -> list[str]:
        return [a for g in self.generators for a in g.axes]

    @property
    def alternate(self) -> bool:
        return self.generators[0].alternate


def _shrink_to_rectangle(
    generators: list[Generator], excluder: _Excluder
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
        positions = gen.positions()
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


def _owner(generators: list[Generator], axis: str, excluder: _Excluder) -> Generator:
    for gen in generators:
        if axis in gen.axes:
            return gen
    raise GeneratorError(
        excluder.path + ".axes", f"axis {axis!r} is not scanned by any generator"
    )


def _merge_dimensions(dims: list[_Dim], excluder: _Excluder) -> list[_Dim]:
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


@dataclass
class _PreparedDim:
    """The points of one dimension after excluding, in forward order."""

    axes: list[str]
    alternate: bool
    size: int
    positions: Arrays
    lower: Arrays
    upper: Arrays


def _prepare(dim: _Dim, bounded: Generator | None, path: str) -> _PreparedDim:
    """Unroll the dimension's generators (snaking within it), apply its
    excluders, and give ``bounded`` (the scan's innermost generator, if it is in
    this dimension and the scan is continuous) its real bounds.

    ``path`` names the dimension's excluder (or generator) in error messages.
    """
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
        gen_positions = gen.positions()
        for axis in gen.axes:
            positions[axis] = np.asarray(gen_positions[axis], dtype=float)[index]
        if gen is bounded:
            gen_bounds = gen.bounds()
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
    return _PreparedDim(
        axes=dim.axes,
        alternate=dim.alternate,
        size=len(indices),
        positions=kept,
        lower={a: lower[a][indices] if a in lower else kept[a] for a in kept},
        upper={a: upper[a][indices] if a in upper else kept[a] for a in kept},
    )


def compound_points(data: Mapping[str, Any]) -> ScanPoints:
    """Compute the scan points of a CompoundGenerator dict.

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
    excluders = [_parse_excluder(v, p) for p, v in fields.items("excluders", [])]
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
    prepared = [
        _prepare(
            dim,
            bounded if i == len(dims) - 1 else None,
            dim.excluders[-1].path if dim.excluders else dim.generators[0].path,
        )
        for i, dim in enumerate(dims)
    ]
    sizes = [d.size for d in prepared]
    total = math.prod(sizes)
    check_size(total, "generators")

    n = np.arange(total)
    positions: Arrays = {}
    lower: Arrays = {}
    upper: Arrays = {}
    repeat = total
    for i, dim in enumerate(prepared):
        size = dim.size
        repeat //= size
        k = n // repeat
        index = k % size
        backwards = dim.alternate & ((k // size) % 2 == 1)
        index = np.where(backwards, size - 1 - index, index)
        for axis in dim.axes:
            positions[axis] = dim.positions[axis][index]
            if i == len(prepared) - 1:
                lower[axis] = np.where(
                    backwards, dim.upper[axis][index], dim.lower[axis][index]
                )
                upper[axis] = np.where(
                    backwards, dim.lower[axis][index], dim.upper[axis][index]
                )
            else:
                lower[axis] = positions[axis]
                upper[axis] = positions[axis]

    axes = [a for g in generators for a in g.axes]
    return ScanPoints(
        axes=axes,
        shape=list(sizes),
        dimensions=[Dimension(list(d.axes), d.size, d.alternate) for d in prepared],
        positions={a: positions[a] for a in axes},
        lower={a: lower[a] for a in axes},
        upper={a: upper[a] for a in axes},
        duration=None if duration is None else np.full(total, duration),
    )

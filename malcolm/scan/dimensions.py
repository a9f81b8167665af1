"""One dimension of a scan, evaluated at the indexes asked for, and a stack
of them (`stack_points`).

A `ScanPoints` is a stack of these, outer -> inner; `stack_points` works out
which index of each dimension a scan step is at (and whether the dimension
is running backwards) and asks each for its points there. A dimension
answers in forward order; the stack swaps lower and upper when it runs
backwards.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Collection, Sequence

import numpy as np

from .generators import Arrays, Generator
from .regions import KeptRuns

#: positions, lower bounds and upper bounds of some axes
Triple = tuple[Arrays, Arrays, Arrays]


class DimensionPoints(ABC):
    """The points of one dimension of a scan, in forward order.

    Attributes:
        axes: The axes that move in this dimension.
        size: Its number of points.
        snake: Whether it runs backwards on every other pass of the dimensions
            outside it.
    """

    axes: list[str]
    size: int
    snake: bool
    #: Whether `durations` gives seconds per point (else it gives None)
    has_durations: bool = False

    @abstractmethod
    def points(
        self, index: np.ndarray, axes: Collection[str], bounds: bool = True
    ) -> Triple:
        """Positions, lower and upper bounds of ``axes`` (some of this
        dimension's) at each forward ``index`` (0 .. size-1). Where an axis
        has no bounds, its lower and upper are its positions (the same array).
        With ``bounds`` False, lower and upper are left empty.
        """

    def durations(
        self, index: np.ndarray, backwards: np.ndarray | None
    ) -> np.ndarray | None:
        """Seconds per point at each forward ``index`` (``backwards`` says where
        the dimension runs backwards), or None."""
        return None


class GeneratorDimension(DimensionPoints):
    """Generators nested outer -> inner as one dimension, snaking within it
    (``alternate``), optionally keeping only the points in ``runs``.

    Without runs each generator is evaluated only at the indexes asked for;
    with runs (a region joined these generators) a kept index is first mapped
    to its index among all the unrolled points.

    Args:
        generators: Outer -> inner.
        bounded: The one generator (of these) whose bounds are real, or None:
            every other axis has lower == upper == position.
        runs: The unrolled indexes kept by the dimension's regions, or None
            for all of them.
    """

    def __init__(
        self,
        generators: Sequence[Generator],
        bounded: Generator | None = None,
        runs: KeptRuns | None = None,
    ) -> None:
        self.generators = list(generators)
        self.bounded = bounded
        self.runs = runs
        self.axes = [a for g in self.generators for a in g.axes]
        #: number of points before any region
        self.unrolled_size = math.prod(g.size for g in self.generators)
        self.size = runs.size if runs is not None else self.unrolled_size
        self.snake = self.generators[0].alternate

    def points(
        self, index: np.ndarray, axes: Collection[str], bounds: bool = True
    ) -> Triple:
        """The points at kept ``index`` (see `DimensionPoints.points`)."""
        if self.runs is not None:
            index = self.runs.unrolled(index)
        return self.unrolled(index, axes, bounds)

    def unrolled(self, t: np.ndarray, axes: Collection[str], bounds: bool) -> Triple:
        """The points at unrolled indexes ``t``, before any region; with
        ``bounds`` False, lower and upper are left empty."""
        positions: Arrays = {}
        lower: Arrays = {}
        upper: Arrays = {}
        after = self.unrolled_size
        for gen in self.generators:
            after //= gen.size
            wanted = [a for a in gen.axes if a in axes]
            if not wanted:
                continue
            index = (t // after) % gen.size if after > 1 else t % gen.size
            backwards = None
            if gen.alternate:
                backwards = (t // (after * gen.size)) % 2 == 1
                index = np.where(backwards, gen.size - 1 - index, index)
            values = gen.positions_at(index)
            for axis in wanted:
                positions[axis] = values[axis]
            if not bounds:
                continue
            if gen is self.bounded:
                if backwards is None and _consecutive(index):
                    # each point's upper bound is the next one's lower: the
                    # n + 1 bounds evaluated once (a curve's a third less)
                    both = gen.bounds_at(np.arange(index[0], index[-1] + 2))
                    for axis in wanted:
                        lower[axis] = both[axis][:-1]
                        upper[axis] = both[axis][1:]
                    continue
                step = 0 if backwards is None else backwards.astype(int)
                low = gen.bounds_at(index + step)
                high = gen.bounds_at(index + 1 - step)
                for axis in wanted:
                    lower[axis] = low[axis]
                    upper[axis] = high[axis]
            else:
                for axis in wanted:
                    lower[axis] = upper[axis] = values[axis]
        return positions, lower, upper


def _consecutive(index: np.ndarray) -> bool:
    """Whether ``index`` is k, k+1, ..., k+n-1 (n > 1)."""
    return (
        len(index) > 1
        and int(index[-1]) - int(index[0]) == len(index) - 1
        and bool(np.all(np.diff(index) == 1))
    )


class ArrayDimension(DimensionPoints):
    """A dimension whose points are held as arrays of its own size (as
    scanspec calculates them).

    Args:
        axes: Its axes.
        positions: Per axis, the position of each point.
        lower: Per axis, the lower bound of each point.
        upper: Per axis, the upper bound of each point.
        snake: Whether it runs backwards on alternate passes.
        size: Its number of points (it may have no axes, only durations).
        durations: Seconds per point, or None.
    """

    def __init__(
        self,
        axes: list[str],
        positions: Arrays,
        lower: Arrays,
        upper: Arrays,
        snake: bool,
        size: int,
        durations: np.ndarray | None = None,
    ) -> None:
        self.axes = axes
        self.positions = positions
        self.lower = lower
        self.upper = upper
        self.snake = snake
        self.size = size
        self._durations = durations
        self.has_durations = durations is not None

    def points(
        self, index: np.ndarray, axes: Collection[str], bounds: bool = True
    ) -> Triple:
        """The held points at ``index``."""
        wanted = [a for a in self.axes if a in axes]
        positions = {a: self.positions[a][index] for a in wanted}
        if not bounds:
            return positions, {}, {}
        return (
            positions,
            {a: self.lower[a][index] for a in wanted},
            {a: self.upper[a][index] for a in wanted},
        )

    def durations(
        self, index: np.ndarray, backwards: np.ndarray | None
    ) -> np.ndarray | None:
        """The held durations; running backwards, the duration of the point
        after, exactly as scanspec's ``Path`` gives them."""
        if self._durations is None:
            return None
        if backwards is not None:
            index = np.where(backwards, (index + 1) % self.size, index)
        return self._durations[index]


def stack_points(
    dims: Sequence[DimensionPoints],
    steps: np.ndarray,
    axes: Collection[str],
    bounds: bool,
    durations: bool,
) -> tuple[Arrays, Arrays, Arrays, np.ndarray | None]:
    """Positions (and lower and upper bounds, and durations, if asked) of
    ``axes`` at the scan's ``steps``, for dimensions ``dims`` (outer -> inner,
    none empty).

    With sizes s0 .. sk, step n is at pass ``n // (s(i+1) * .. * sk)`` of
    dimension i, at index ``pass % si``, backwards if the dimension snakes and
    ``pass // si`` is odd; backwards, lower and upper swap.
    """
    positions: Arrays = {}
    lower: Arrays = {}
    upper: Arrays = {}
    timed = None
    repeat = math.prod(d.size for d in dims)
    with np.errstate(all="ignore"):
        for dim in dims:
            repeat //= dim.size
            wanted = [a for a in dim.axes if a in axes]
            timing = durations and dim.has_durations
            if not wanted and not timing:
                continue
            passes = steps // repeat if repeat > 1 else steps
            index = passes % dim.size
            backwards = None
            if dim.snake:
                backwards = (passes // dim.size) % 2 == 1
                index = np.where(backwards, dim.size - 1 - index, index)
            if timing:
                timed = dim.durations(index, backwards)
            if not wanted:
                continue
            pos, low, high = dim.points(index, wanted, bounds)
            positions.update(pos)
            if not bounds:
                continue
            for axis in wanted:
                if backwards is not None and low[axis] is not high[axis]:
                    low[axis], high[axis] = (
                        np.where(backwards, high[axis], low[axis]),
                        np.where(backwards, low[axis], high[axis]),
                    )
                lower[axis] = low[axis]
                upper[axis] = high[axis]
    return positions, lower, upper, timed

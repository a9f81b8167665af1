"""The computed points of a scan, whatever described it."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass
class Dimension:
    """One dimension of the scan's shape.

    Attributes:
        axes: The axes that move within this dimension (several for a spiral, a
            zip, or generators joined by a region; none for a static repeat).
        size: Number of points along the dimension.
        snake: Whether the dimension runs backwards on every other pass of the
            dimensions outside it.
    """

    axes: list[str]
    size: int
    snake: bool


@dataclass
class ScanPoints:
    """Every point of a scan, in scan order.

    Attributes:
        axes: All axes of the scan, outer -> inner.
        shape: Size of each dimension, outer -> inner.
        dimensions: The dimensions, outer -> inner; the product of their sizes is
            `size`.
        positions: For each axis, its demand position at each point.
        lower: For each axis, its position at the start of each point (for fly
            scanning; equal to the position for axes that do not fly).
        upper: For each axis, its position at the end of each point.
        duration: Seconds per point, or None if the scan does not say.
    """

    axes: list[str]
    shape: list[int]
    dimensions: list[Dimension]
    positions: dict[str, np.ndarray]
    lower: dict[str, np.ndarray]
    upper: dict[str, np.ndarray]
    duration: np.ndarray | None

    @property
    def size(self) -> int:
        """Total number of points."""
        return math.prod(self.shape)

    def steps_per_run(self, axes_to_move: Sequence[str] | None) -> int:
        """Number of points a run covers when only ``axes_to_move`` may move.

        The run is made of the innermost dimensions, taken from the inside out
        until every axis in ``axes_to_move`` is covered; all the axes of those
        dimensions must be in ``axes_to_move``. ``None`` means every axis (the
        whole scan is one run); an empty list means 1 (every point is a run).

        Raises:
            ValueError: naming the axis, if ``axes_to_move`` names an axis the
                scan does not have, or if the moving axes are not the innermost
                dimensions (e.g. moving y but not x when x is inside y).
        """
        if axes_to_move is None:
            return self.size
        if isinstance(axes_to_move, str):
            raise TypeError("axes_to_move must be a sequence of axis names, not a str")
        for axis in axes_to_move:
            if axis not in self.axes:
                raise ValueError(
                    f"axis {axis!r} in axes_to_move is not an axis of this scan "
                    f"{self.axes}"
                )
        remaining = set(axes_to_move)
        steps = 1
        for dim in reversed(self.dimensions):
            if not remaining:
                break
            for axis in dim.axes:
                if axis not in remaining:
                    moving = sorted(remaining)
                    raise ValueError(
                        f"axis {axis!r} is not in axes_to_move but is in a "
                        f"dimension inside (or shared with) {moving}; only the "
                        f"innermost dimensions can be moved"
                    )
            remaining.difference_update(dim.axes)
            steps *= dim.size
        return steps

    def point(self, index: int) -> dict[str, float]:
        """The position of every axis at point ``index`` (negative counts from
        the end)."""
        size = self.size
        if not -size <= index < size:
            raise IndexError(f"point {index} is out of range for {size} points")
        return {axis: float(self.positions[axis][index]) for axis in self.axes}

    def to_json(self) -> dict[str, Any]:
        """A JSON-ready dict: ``axes``, ``size``, ``shape``, and per axis lists of
        ``positions``, ``lower``, ``upper``, plus ``duration`` (a list or
        None)."""

        def lists(arrays: dict[str, np.ndarray]) -> dict[str, list[float]]:
            return {a: [float(v) for v in arrays[a]] for a in self.axes}

        return {
            "axes": list(self.axes),
            "size": self.size,
            "shape": list(self.shape),
            "positions": lists(self.positions),
            "lower": lists(self.lower),
            "upper": lists(self.upper),
            "duration": None
            if self.duration is None
            else [float(v) for v in self.duration],
        }

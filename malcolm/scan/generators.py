"""The scanpointgenerator generators, parsed from the dicts GDA sends.

Each generator knows its axes, its number of points and whether it runs
backwards on every other pass (``alternate``), and computes its positions and
its bounds at any indexes asked for, so a scan never needs all of them at
once. Positions are sampled at indexes ``0 .. size-1`` of the generator's
parametric curve and bounds at the half-indexes ``-0.5 .. size-0.5`` (so there
is one more bound than positions), which is how scanpointgenerator 3.x defines
them. The generators that hold others (zip, concat) are in
`malcolm.scan.nested`.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from typing import Any

import numpy as np

from .errors import GeneratorError
from .fields import Fields, describe

PREFIX = "scanpointgenerator:generator/"
COMPOUND_TYPEID = PREFIX + "CompoundGenerator:1.0"

#: Largest number of points (before or after excluding) we agree to compute.
MAX_POINTS = 100_000_000

Arrays = dict[str, np.ndarray]


def check_size(size: int, path: str) -> None:
    """Reject a generator or scan too big to compute."""
    if size > MAX_POINTS:
        raise GeneratorError(
            path, f"scan would have {size} points, more than the {MAX_POINTS} allowed"
        )


def units_of(fields: Fields, axes: list[str]) -> list[str]:
    """Units are optional; a single unit applies to every axis."""
    units = fields.string_list("units", default=[""] * len(axes))
    if len(units) == 1 and len(axes) != 1:
        units = units * len(axes)
    if len(units) != len(axes):
        raise GeneratorError(
            fields.at("units"),
            f"expected {len(axes)} units (one per axis), got {len(units)}",
        )
    return units


class Generator(ABC):
    """One scanpointgenerator generator (not the CompoundGenerator).

    Subclasses compute positions and bounds at any integer indexes; the
    values at an index do not depend on which other indexes are asked for in
    the same call, so a chunk of a scan is exactly the same slice of the whole.
    """

    def __init__(
        self, path: str, axes: list[str], units: list[str], size: int, alternate: bool
    ) -> None:
        #: Where this generator sits in the input, for error messages
        self.path = path
        self.axes = axes
        self.units = units
        self.size = size
        self.alternate = alternate

    @abstractmethod
    def positions_at(self, index: np.ndarray) -> Arrays:
        """Position of each axis at each of the integer ``index`` (0 .. size-1)."""

    @abstractmethod
    def bounds_at(self, index: np.ndarray) -> Arrays:
        """Bound of each axis at each integer ``index`` (0 .. size): point i
        runs from bound i to bound i+1."""

    @abstractmethod
    def extremes(self, bounds: bool) -> list[tuple[str, str, Any]]:
        """``(path, axis, values)`` for a few values per axis (an array, or a
        list of floats) such that, if they are all finite, so is every
        position (and every bound if ``bounds``).

        Used to refuse absurdly large inputs without computing every point.
        """

    def check_bounds(self) -> None:
        """Raise `GeneratorError` if this generator's bounds cannot be used
        (a concat whose pieces do not join); called only when they are. A
        single curve's bounds always can."""
        return None

    def positions(self) -> Arrays:
        """Every position (``size`` per axis): memory grows with the size."""
        return self.positions_at(np.arange(self.size))

    def bounds(self) -> Arrays:
        """Every bound (``size + 1`` per axis): memory grows with the size."""
        return self.bounds_at(np.arange(self.size + 1))


class CurveGenerator(Generator):
    """A generator defined by a parametric curve evaluated at indexes."""

    @abstractmethod
    def _arrays(self, index: np.ndarray) -> Arrays:
        """Evaluate the curve at (possibly fractional) float indexes."""

    def positions_at(self, index: np.ndarray) -> Arrays:
        """The curve at the integer indexes."""
        return self._arrays(np.asarray(index).astype(float))

    def bounds_at(self, index: np.ndarray) -> Arrays:
        """The curve half an index before each integer index."""
        return self._arrays(np.asarray(index).astype(float) - 0.5)


class LineGenerator(CurveGenerator):
    """Equally spaced points from ``start`` to ``stop`` on one or more axes."""

    def __init__(
        self,
        path: str,
        axes: list[str],
        units: list[str],
        start: list[float],
        stop: list[float],
        size: int,
        alternate: bool,
    ) -> None:
        super().__init__(path, axes, units, size, alternate)
        self.start = start
        self.stop = stop

    @classmethod
    def parse(cls, fields: Fields) -> LineGenerator:
        """Build from a LineGenerator dict."""
        axes = fields.axes()
        units = units_of(fields, axes)
        start = fields.number_list("start", len(axes))
        stop = fields.number_list("stop", len(axes))
        size = fields.positive_int("size")
        alternate = fields.boolean("alternate", default=False)
        return cls(fields.path, axes, units, start, stop, size, alternate)

    def _arrays(self, index: np.ndarray) -> Arrays:
        arrays = {}
        for axis, start, stop in zip(self.axes, self.start, self.stop):
            step = stop - start
            if self.size > 1:
                step /= self.size - 1
            else:
                # A single point sits midway; its bounds are start and stop
                start = (start + stop) / 2.0
            if isinstance(index, tuple):  # a few Python floats (extremes)
                arrays[axis] = [i * step + start for i in index]
            else:
                arrays[axis] = index * step + start
        return arrays

    def extremes(self, bounds: bool) -> list[tuple[str, str, Any]]:
        """The line at its first and last index (and bound): it is monotonic.

        Evaluated with Python floats, which follow the same IEEE rules as the
        arrays (an overflow is inf, inf times 0 is nan), at a fraction of the
        cost of numpy on two-element arrays: every configure pays this."""
        last = float(self.size - 1)
        index = (0.0, last, -0.5, last + 0.5) if bounds else (0.0, last)
        curve = self._arrays(index)  # type: ignore[arg-type]
        return [(self.path, a, curve[a]) for a in self.axes]


class SpiralGenerator(CurveGenerator):
    """An Archimedean spiral out from ``centre`` to ``radius``.

    The angle at (fractional) index t is ``phi = sqrt(4 pi (t + 0.5))`` and the
    radius ``phi * scale / (2 pi)``, so successive rings are ``scale`` apart
    and points are roughly evenly spread over the area. The number of points
    is the largest that stays within ``radius``.
    """

    def __init__(
        self,
        path: str,
        axes: list[str],
        units: list[str],
        centre: list[float],
        radius: float,
        scale: float,
        alternate: bool,
    ) -> None:
        self.centre = centre
        self.radius = radius
        self.scale = scale
        self._alpha = math.sqrt(4 * math.pi)
        self._beta = scale / (2 * math.pi)
        rings = radius / (self._alpha * self._beta)
        if rings > math.sqrt(MAX_POINTS):
            raise GeneratorError(
                path,
                f"spiral would have more than {MAX_POINTS} points "
                f"(radius {radius:g}, scale {scale:g})",
            )
        size_f = rings**2
        super().__init__(path, axes, units, int(size_f) + 1, alternate)

    @classmethod
    def parse(cls, fields: Fields) -> SpiralGenerator:
        """Build from a SpiralGenerator dict."""
        axes = fields.axes(count=2)
        units = units_of(fields, axes)
        centre = fields.number_list("centre", 2)
        radius = fields.number("radius")
        if radius < 0:
            raise GeneratorError(
                fields.at("radius"),
                f"expected a non-negative number, got {describe(radius)}",
            )
        scale = fields.positive_number("scale", default=1.0)
        alternate = fields.boolean("alternate", default=False)
        return cls(fields.path, axes, units, centre, radius, scale, alternate)

    def _phi(self, index: np.ndarray) -> np.ndarray:
        return self._alpha * np.sqrt(index + 0.5)

    def _arrays(self, index: np.ndarray) -> Arrays:
        phi = self._phi(index)
        return {
            self.axes[0]: self.centre[0] + self._beta * phi * np.sin(phi),
            self.axes[1]: self.centre[1] + self._beta * phi * np.cos(phi),
        }

    def extremes(self, bounds: bool) -> list[tuple[str, str, np.ndarray]]:
        """The centre +- the largest radius: the angle grows with the index,
        and a sine or cosine never exceeds 1."""
        # the largest index evaluated, as bounds_at or positions_at has it
        last = np.array([self.size - 0.5 if bounds else self.size - 1.0])
        reach = self._beta * self._phi(last)
        return [
            (self.path, axis, np.concatenate([centre - reach, centre + reach]))
            for axis, centre in zip(self.axes, self.centre)
        ]


class LissajousGenerator(CurveGenerator):
    """A Lissajous curve filling the box ``centre`` +- ``span`` / 2.

    The first axis makes ``lobes`` oscillations and the second ``lobes + 1``
    over the ``size`` points; the first axis has a quarter-period phase shift
    when ``lobes`` is odd.
    """

    def __init__(
        self,
        path: str,
        axes: list[str],
        units: list[str],
        centre: list[float],
        span: list[float],
        lobes: int,
        size: int,
        alternate: bool,
    ) -> None:
        super().__init__(path, axes, units, size, alternate)
        self.centre = centre
        self.span = span
        self.lobes = lobes
        self._x_freq = lobes
        self._y_freq = lobes + 1
        self._x_max = span[0] / 2
        self._y_max = span[1] / 2
        self._phase = math.pi / 2 * (lobes % 2)
        self._increment = 2 * math.pi / size

    @classmethod
    def parse(cls, fields: Fields) -> LissajousGenerator:
        """Build from a LissajousGenerator dict (``size`` defaults to 250 *
        lobes)."""
        axes = fields.axes(count=2)
        units = units_of(fields, axes)
        centre = fields.number_list("centre", 2)
        span = fields.number_list("span", 2)
        lobes = fields.positive_int("lobes")
        size = fields.positive_int("size", default=lobes * 250)
        alternate = fields.boolean("alternate", default=False)
        return cls(fields.path, axes, units, centre, span, lobes, size, alternate)

    def _arrays(self, index: np.ndarray) -> Arrays:
        x = self._x_freq * self._increment * index + self._phase
        y = self._y_freq * self._increment * index
        return {
            self.axes[0]: self.centre[0] + self._x_max * np.sin(x),
            self.axes[1]: self.centre[1] + self._y_max * np.sin(y),
        }

    def extremes(self, bounds: bool) -> list[tuple[str, str, np.ndarray]]:
        """The corners of the box the curve stays in."""
        return [
            (self.path, axis, np.array([centre - half, centre + half]))
            for axis, centre, half in zip(
                self.axes, self.centre, (abs(self._x_max), abs(self._y_max))
            )
        ]


class ArrayGenerator(CurveGenerator):
    """Points at the given ``points`` of one axis; bounds interpolate linearly
    between neighbours (and extrapolate beyond the ends)."""

    def __init__(
        self,
        path: str,
        axes: list[str],
        units: list[str],
        points: list[float],
        alternate: bool,
    ) -> None:
        super().__init__(path, axes, units, len(points), alternate)
        self.points = points
        p = np.asarray(points, dtype=float)
        # One extra point at each end continuing the first and last steps
        self._extended = np.concatenate(
            ([p[0] - (p[1] - p[0])], p, [p[-1] + (p[-1] - p[-2])])
        )

    @classmethod
    def parse(cls, fields: Fields) -> ArrayGenerator:
        """Build from an ArrayGenerator dict (``axis`` is accepted for
        ``axes``, as scanpointgenerator does)."""
        key = "axis" if fields.has("axis") and not fields.has("axes") else "axes"
        axes = fields.axes(key, count=1)
        units = units_of(fields, axes)
        points = fields.number_list("points")
        if len(points) < 2:
            raise GeneratorError(
                fields.at("points"), f"expected at least 2 points, got {len(points)}"
            )
        alternate = fields.boolean("alternate", default=False)
        return cls(fields.path, axes, units, points, alternate)

    def _arrays(self, index: np.ndarray) -> Arrays:
        extended = self._extended
        whole = np.floor(index).astype(int)
        fraction = index - whole
        below = extended[whole + 1]
        return {self.axes[0]: below + fraction * (extended[whole + 2] - below)}

    def extremes(self, bounds: bool) -> list[tuple[str, str, np.ndarray]]:
        """Every value: the points are in the input already."""
        arrays = [self.positions()] + ([self.bounds()] if bounds else [])
        return [(self.path, self.axes[0], values[self.axes[0]]) for values in arrays]


class StaticGenerator(Generator):
    """``size`` repeats of the same point, with no axis or with one axis whose
    value counts 1, 2, ... ``size``."""

    @classmethod
    def parse(cls, fields: Fields) -> StaticGenerator:
        """Build from a StaticPointGenerator dict."""
        size = fields.positive_int("size")
        axes = fields.axes() if fields.has("axes") else []
        if len(axes) > 1:
            raise GeneratorError(
                fields.at("axes"), f"expected at most 1 axis, got {len(axes)}"
            )
        units = units_of(fields, axes) if axes else []
        return cls(fields.path, axes, units, size, False)

    # scanpointgenerator numbers the points from 1, and the bounds too
    def positions_at(self, index: np.ndarray) -> Arrays:
        """Point i is at i + 1."""
        return {axis: np.asarray(index) + 1.0 for axis in self.axes}

    def bounds_at(self, index: np.ndarray) -> Arrays:
        """Bound i is at i + 1 (as scanpointgenerator has it)."""
        return {axis: np.asarray(index) + 1.0 for axis in self.axes}

    def extremes(self, bounds: bool) -> list[tuple[str, str, np.ndarray]]:
        """Nothing to check: counting to at most MAX_POINTS + 1."""
        return []

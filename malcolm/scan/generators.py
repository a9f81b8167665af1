"""The scanpointgenerator generators, parsed from the dicts GDA sends.

Each generator knows its axes, its number of points and whether it runs
backwards on every other pass (``alternate``), and computes its positions and
its bounds. Positions are sampled at indexes ``0 .. size-1`` of the generator's
parametric curve and bounds at the half-indexes ``-0.5 .. size-0.5`` (so there
is one more bound than positions), which is how scanpointgenerator 3.x defines
them.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable
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


def _units(fields: Fields, axes: list[str]) -> list[str]:
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
    """One scanpointgenerator generator (not the CompoundGenerator)."""

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
    def positions(self) -> Arrays:
        """Position of each axis at each of the ``size`` points."""

    @abstractmethod
    def bounds(self) -> Arrays:
        """``size + 1`` bounds for each axis: point i runs from bound i to i+1."""


class CurveGenerator(Generator):
    """A generator defined by a parametric curve evaluated at indexes."""

    @abstractmethod
    def _arrays(self, index: np.ndarray) -> Arrays:
        """Evaluate the curve at (possibly fractional) indexes."""

    def positions(self) -> Arrays:
        """The curve at indexes 0 .. size-1."""
        return self._arrays(np.arange(self.size, dtype=float))

    def bounds(self) -> Arrays:
        """The curve at indexes -0.5 .. size-0.5."""
        return self._arrays(np.arange(self.size + 1, dtype=float) - 0.5)


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
        units = _units(fields, axes)
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
            arrays[axis] = index * step + start
        return arrays


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
        units = _units(fields, axes)
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

    def _arrays(self, index: np.ndarray) -> Arrays:
        phi = self._alpha * np.sqrt(index + 0.5)
        return {
            self.axes[0]: self.centre[0] + self._beta * phi * np.sin(phi),
            self.axes[1]: self.centre[1] + self._beta * phi * np.cos(phi),
        }


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
        units = _units(fields, axes)
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

    @classmethod
    def parse(cls, fields: Fields) -> ArrayGenerator:
        """Build from an ArrayGenerator dict (``axis`` is accepted for
        ``axes``, as scanpointgenerator does)."""
        key = "axis" if fields.has("axis") and not fields.has("axes") else "axes"
        axes = fields.axes(key, count=1)
        units = _units(fields, axes)
        points = fields.number_list("points")
        if len(points) < 2:
            raise GeneratorError(
                fields.at("points"), f"expected at least 2 points, got {len(points)}"
            )
        alternate = fields.boolean("alternate", default=False)
        return cls(fields.path, axes, units, points, alternate)

    def _arrays(self, index: np.ndarray) -> Arrays:
        p = np.asarray(self.points, dtype=float)
        # One extra point at each end continuing the first and last steps
        extended = np.concatenate(
            ([p[0] - (p[1] - p[0])], p, [p[-1] + (p[-1] - p[-2])])
        )
        whole = np.floor(index).astype(int)
        fraction = index - whole
        below = extended[whole + 1]
        return {self.axes[0]: below + fraction * (extended[whole + 2] - below)}


class StaticGenerator(CurveGenerator):
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
        units = _units(fields, axes) if axes else []
        return cls(fields.path, axes, units, size, False)

    def _arrays(self, index: np.ndarray) -> Arrays:
        # scanpointgenerator numbers the points from 1, bounds included
        return {axis: np.arange(1, len(index) + 1, dtype=float) for axis in self.axes}


class ZipGenerator(Generator):
    """Several generators of equal size run in step, one point from each."""

    def __init__(self, path: str, generators: list[Generator], alternate: bool) -> None:
        self.generators = generators
        axes = [a for g in generators for a in g.axes]
        units = [u for g in generators for u in g.units]
        super().__init__(path, axes, units, generators[0].size, alternate)

    @classmethod
    def parse(cls, fields: Fields) -> ZipGenerator:
        """Build from a ZipGenerator dict."""
        generators = _parse_children(fields, "zip")
        seen: dict[str, str] = {}
        for gen in generators:
            if gen.size != generators[0].size:
                raise GeneratorError(
                    gen.path,
                    f"all generators in a ZipGenerator must have the same size: "
                    f"this one has {gen.size}, the first has {generators[0].size}",
                )
            for axis in gen.axes:
                if axis in seen:
                    raise GeneratorError(
                        gen.path, f"axis {axis!r} is already used by {seen[axis]}"
                    )
                seen[axis] = gen.path
        alternate = fields.boolean("alternate", default=False)
        return cls(fields.path, generators, alternate)

    def positions(self) -> Arrays:
        """Union of the children's positions."""
        return {k: v for g in self.generators for k, v in g.positions().items()}

    def bounds(self) -> Arrays:
        """Union of the children's bounds."""
        return {k: v for g in self.generators for k, v in g.bounds().items()}


class ConcatGenerator(Generator):
    """Several generators on the same axes, run one after the other."""

    #: How far apart the last bound of one child and the first bound of the next
    #: may be (scanpointgenerator's limit)
    BOUNDS_TOLERANCE = 1e-5

    def __init__(self, path: str, generators: list[Generator], alternate: bool) -> None:
        self.generators = generators
        size = sum(g.size for g in generators)
        super().__init__(path, generators[0].axes, generators[0].units, size, alternate)

    @classmethod
    def parse(cls, fields: Fields) -> ConcatGenerator:
        """Build from a ConcatGenerator dict."""
        generators = _parse_children(fields, "concat")
        first = generators[0]
        for gen in generators[1:]:
            if gen.axes != first.axes:
                raise GeneratorError(
                    gen.path,
                    f"all generators in a ConcatGenerator must have the same axes: "
                    f"this one has {gen.axes}, the first has {first.axes}",
                )
            if gen.units != first.units:
                raise GeneratorError(
                    gen.path,
                    f"all generators in a ConcatGenerator must have the same units: "
                    f"this one has {gen.units}, the first has {first.units}",
                )
        alternate = fields.boolean("alternate", default=False)
        return cls(fields.path, generators, alternate)

    def positions(self) -> Arrays:
        """The children's positions one after the other."""
        parts = [g.positions() for g in self.generators]
        return {a: np.concatenate([p[a] for p in parts]) for a in self.axes}

    def bounds(self) -> Arrays:
        """The children's bounds joined: the upper bound ending one child must be
        the lower bound starting the next."""
        parts = [g.bounds() for g in self.generators]
        result = {}
        for axis in self.axes:
            pieces = [parts[0][axis]]
            for gen, part in zip(self.generators[1:], parts[1:]):
                end, begin = float(pieces[-1][-1]), float(part[axis][0])
                if abs(end - begin) >= self.BOUNDS_TOLERANCE:
                    raise GeneratorError(
                        gen.path,
                        f"bounds of axis {axis!r} do not join the previous "
                        f"generator's ({begin:g} != {end:g}); a continuous scan "
                        f"needs them to meet (or set continuous to false)",
                    )
                pieces[-1] = pieces[-1][:-1]
                pieces.append(part[axis])
            result[axis] = np.concatenate(pieces)
        return result


def _parse_children(fields: Fields, kind: str) -> list[Generator]:
    items = fields.items("generators")
    if not items:
        raise GeneratorError(fields.at("generators"), "expected at least one generator")
    children = [parse_generator(value, path) for path, value in items]
    for child in children:
        if child.alternate:
            raise GeneratorError(
                child.path + ".alternate",
                f"must be false inside a {kind} generator; "
                f"set alternate on the {kind} generator itself",
            )
    return children


_PARSERS: dict[str, Callable[[Fields], Generator]] = {
    PREFIX + "LineGenerator:1.0": LineGenerator.parse,
    PREFIX + "SpiralGenerator:1.0": SpiralGenerator.parse,
    PREFIX + "LissajousGenerator:1.0": LissajousGenerator.parse,
    PREFIX + "ArrayGenerator:1.0": ArrayGenerator.parse,
    PREFIX + "StaticPointGenerator:1.0": StaticGenerator.parse,
    # Not a scanpointgenerator typeid, accepted as an alias
    PREFIX + "StaticGenerator:1.0": StaticGenerator.parse,
    PREFIX + "ZipGenerator:1.0": ZipGenerator.parse,
    PREFIX + "ConcatGenerator:1.0": ConcatGenerator.parse,
}


def parse_generator(data: Any, path: str) -> Generator:
    """Parse one generator dict found at ``path`` of the input."""
    fields = Fields(data, path)
    typeid = fields.string("typeid")
    if typeid == COMPOUND_TYPEID:
        raise GeneratorError(
            path, "a CompoundGenerator cannot be nested; nest its generators instead"
        )
    parser = _PARSERS.get(typeid)
    if parser is None:
        raise GeneratorError(path, f"unknown typeid {typeid!r}")
    generator = parser(fields)
    fields.check_no_extra()
    check_size(generator.size, path)
    return generator

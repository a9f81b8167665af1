"""Regions of interest for ROIExcluder, parsed from scanpointgenerator dicts.

Each ROI turns arrays of x and y positions (the excluder's first and second
axis) into a boolean mask that is True where the point is inside the region.
Points on the boundary count as inside.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import Any

import numpy as np

from .errors import GeneratorError
from .fields import Fields, describe

PREFIX = "scanpointgenerator:roi/"


class ROI(ABC):
    """A 2D region in the plane of an excluder's two axes."""

    @abstractmethod
    def mask(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """True for each (x, y) inside the region."""


def _rotate(x: np.ndarray, y: np.ndarray, angle: float) -> tuple[np.ndarray, ...]:
    """Express (x, y) in a frame rotated by ``angle`` radians."""
    if angle == 0:
        return x, y
    c, s = math.cos(-angle), math.sin(-angle)
    return x * c - y * s, x * s + y * c


class RectangularROI(ROI):
    """Rectangle with a corner at ``start``, ``width`` along x and ``height``
    along y, rotated by ``angle`` radians about ``start``."""

    def __init__(
        self, start: list[float], width: float, height: float, angle: float
    ) -> None:
        self.start = start
        self.width = width
        self.height = height
        self.angle = angle

    @classmethod
    def parse(cls, fields: Fields) -> RectangularROI:
        """Build from a RectangularROI dict."""
        return cls(
            fields.number_list("start", 2),
            fields.positive_number("width"),
            fields.positive_number("height"),
            fields.number("angle", default=0.0),
        )

    def mask(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Inside the (rotated) rectangle, edges included."""
        rx, ry = _rotate(x - self.start[0], y - self.start[1], self.angle)
        return (rx >= 0) & (rx <= self.width) & (ry >= 0) & (ry <= self.height)


class CircularROI(ROI):
    """Disc of ``radius`` about ``centre``."""

    def __init__(self, centre: list[float], radius: float) -> None:
        self.centre = centre
        self.radius = radius

    @classmethod
    def parse(cls, fields: Fields) -> CircularROI:
        """Build from a CircularROI dict."""
        return cls(fields.number_list("centre", 2), fields.positive_number("radius"))

    def mask(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Within ``radius`` of the centre."""
        dx = x - self.centre[0]
        dy = y - self.centre[1]
        return dx * dx + dy * dy <= self.radius * self.radius


class EllipticalROI(ROI):
    """Ellipse about ``centre`` with ``semiaxes`` [along x, along y], rotated by
    ``angle`` radians."""

    def __init__(
        self, centre: list[float], semiaxes: list[float], angle: float
    ) -> None:
        self.centre = centre
        self.semiaxes = semiaxes
        self.angle = angle

    @classmethod
    def parse(cls, fields: Fields) -> EllipticalROI:
        """Build from an EllipticalROI dict."""
        centre = fields.number_list("centre", 2)
        semiaxes = fields.number_list("semiaxes", 2)
        for i, value in enumerate(semiaxes):
            if value <= 0:
                raise GeneratorError(
                    f"{fields.at('semiaxes')}[{i}]",
                    f"expected a positive number, got {describe(value)}",
                )
        return cls(centre, semiaxes, fields.number("angle", default=0.0))

    def mask(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Inside the (rotated) ellipse."""
        rx, ry = _rotate(x - self.centre[0], y - self.centre[1], self.angle)
        a, b = self.semiaxes
        return (rx * rx) / (a * a) + (ry * ry) / (b * b) <= 1


class PolygonalROI(ROI):
    """Polygon with vertices (``points_x[i]``, ``points_y[i]``), even-odd rule."""

    def __init__(self, points_x: list[float], points_y: list[float]) -> None:
        self.points_x = points_x
        self.points_y = points_y

    @classmethod
    def parse(cls, fields: Fields) -> PolygonalROI:
        """Build from a PolygonalROI dict."""
        xs = fields.number_list("points_x")
        ys = fields.number_list("points_y", len(xs))
        if len(xs) < 3:
            raise GeneratorError(
                fields.at("points_x"),
                f"a polygon needs 3 or more vertices, got {len(xs)}",
            )
        return cls(xs, ys)

    def mask(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Inside by ray casting along +x: an odd number of edge crossings."""
        inside = np.zeros(len(x), dtype=bool)
        x1, y1 = self.points_x[-1], self.points_y[-1]
        for x2, y2 in zip(self.points_x, self.points_y):
            if y1 != y2:  # a horizontal edge is never crossed
                spans = ((y >= y1) & (y < y2)) | ((y >= y2) & (y < y1))
                crossing_x = x1 + (y - y1) / (y2 - y1) * (x2 - x1)
                inside ^= spans & (x < crossing_x)
            x1, y1 = x2, y2
        return inside


class SectorROI(ROI):
    """Annular sector about ``centre``: distance between ``radii`` [inner,
    outer], angle (radians, anticlockwise from +x) from ``angles[0]`` round to
    ``angles[1]``."""

    def __init__(
        self, centre: list[float], radii: list[float], angles: list[float]
    ) -> None:
        self.centre = centre
        self.radii = radii
        start, stop = angles
        if stop < start:
            stop += 2 * math.pi
        if stop < start or stop - start >= 2 * math.pi:
            start, sweep = 0.0, 2 * math.pi
        else:
            sweep = stop - start
            start %= 2 * math.pi
        self._start = start
        self._sweep = sweep

    @classmethod
    def parse(cls, fields: Fields) -> SectorROI:
        """Build from a SectorROI dict."""
        centre = fields.number_list("centre", 2)
        radii = fields.number_list("radii", 2)
        if radii[0] < 0 or radii[1] <= 0 or radii[1] < radii[0]:
            raise GeneratorError(
                fields.at("radii"),
                f"expected 0 <= inner <= outer with outer > 0, got {radii}",
            )
        return cls(centre, radii, fields.number_list("angles", 2))

    def mask(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Between the radii and within the angular sweep."""
        dx = x - self.centre[0]
        dy = y - self.centre[1]
        r2 = dx * dx + dy * dy
        inner, outer = self.radii
        phi = np.mod(np.arctan2(dy, dx) - self._start, 2 * math.pi)
        return (r2 >= inner * inner) & (r2 <= outer * outer) & (phi <= self._sweep)


class PointROI(ROI):
    """A single point: only positions exactly equal to ``point`` are inside."""

    def __init__(self, point: list[float]) -> None:
        self.point = point

    @classmethod
    def parse(cls, fields: Fields) -> PointROI:
        """Build from a PointROI dict."""
        return cls(fields.number_list("point", 2))

    def mask(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Exactly at the point."""
        return (x == self.point[0]) & (y == self.point[1])


_PARSERS: dict[str, Callable[[Fields], ROI]] = {
    PREFIX + "RectangularROI:1.0": RectangularROI.parse,
    PREFIX + "CircularROI:1.0": CircularROI.parse,
    PREFIX + "EllipticalROI:1.0": EllipticalROI.parse,
    PREFIX + "PolygonalROI:1.0": PolygonalROI.parse,
    PREFIX + "SectorROI:1.0": SectorROI.parse,
    PREFIX + "PointROI:1.0": PointROI.parse,
}


def parse_roi(data: Any, path: str) -> ROI:
    """Parse one ROI dict found at ``path`` of the input."""
    fields = Fields(data, path)
    typeid = fields.string("typeid")
    parser = _PARSERS.get(typeid)
    if parser is None:
        raise GeneratorError(path, f"unknown typeid {typeid!r}")
    roi = parser(fields)
    fields.check_no_extra()
    return roi

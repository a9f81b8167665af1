"""The points of a scan, whatever described it, computed for the steps asked.

A `ScanPoints` holds its dimensions (each knows how to compute its own
points) and nothing of the size of the whole scan: a step's index in each
dimension, and whether that dimension runs backwards, is index arithmetic.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .dimensions import DimensionPoints, stack_points

#: Steps per chunk when a scan is walked a chunk at a time (`ScanPoints.chunks`)
CHUNK_SIZE = 65536

Arrays = dict[str, np.ndarray]


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


@dataclass(frozen=True, eq=False)
class Chunk:
    """The points of the steps ``start .. stop-1`` of a scan.

    Attributes:
        start: The first step.
        stop: One past the last step.
        positions: Per axis, its demand position at each step.
        lower: Per axis, its position at the start of each step (equal to the
            position where the axis does not fly).
        upper: Per axis, its position at the end of each step.
        duration: Seconds per step, or None if the scan does not say.
    """

    start: int
    stop: int
    positions: Arrays
    lower: Arrays
    upper: Arrays
    duration: np.ndarray | None

    def __len__(self) -> int:
        return self.stop - self.start


def _integer(name: str, value: Any) -> int:
    """``value`` as an int (a numpy integer will do, a float will not)."""
    try:
        return operator.index(value)
    except TypeError:
        raise TypeError(
            f"{name} must be an integer, got {type(value).__name__}"
        ) from None


def _chunk_size(value: Any) -> int:
    size = _integer("chunk_size", value)
    if size < 1:
        raise ValueError(f"chunk_size must be at least 1, got {size}")
    return size


def _frozen(values: np.ndarray) -> np.ndarray:
    values.flags.writeable = False
    return values


def _read_only(arrays: Arrays) -> Arrays:
    for values in arrays.values():
        _frozen(values)
    return arrays


class ScanPoints:
    """The points of a scan, in scan order, computed when asked for.

    Cheap whatever the scan's size: `axes`, `shape`, `dimensions`, `size`,
    `steps_per_run`, `has_duration`, and the points of a few steps:
    `chunk` (and `chunks`), `point`, `position`, `duration_at`. Computing
    ``n`` steps costs time and memory in proportion to ``n``.

    The memory-hungry way, kept for small scans and old callers: `positions`,
    `lower`, `upper` and `duration` are whole-scan arrays (one value per
    step), computed on first use and then kept; `to_json` is the whole scan
    as lists. A 100-million-point scan needs 800 MB per array.

    Arrays handed out are read-only. `ScanPoints` is not changed by any of
    its methods except to keep those whole-scan arrays, so it may be used
    from several threads (e.g. built off the event loop and read on it).

    Args:
        dimensions: The scan's dimensions, outer -> inner.
        duration: Seconds per point for every point; only when no dimension
            has durations of its own.
    """

    def __init__(
        self, dimensions: Sequence[DimensionPoints], duration: float | None = None
    ) -> None:
        self._dims = list(dimensions)
        self._duration = duration
        timed = [d for d in self._dims if d.has_durations]
        if len(timed) + (duration is not None) > 1:
            raise ValueError("only one dimension, or the scan, may give durations")
        self._timed = bool(timed) or duration is not None
        #: All axes of the scan, outer -> inner
        self.axes: list[str] = [a for d in self._dims for a in d.axes]
        #: Size of each dimension, outer -> inner
        self.shape: list[int] = [d.size for d in self._dims]
        #: The dimensions, outer -> inner; the product of their sizes is `size`
        self.dimensions: list[Dimension] = [
            Dimension(list(d.axes), d.size, d.snake) for d in self._dims
        ]
        self._size = math.prod(self.shape)
        self._full: dict[str, Any] = {}
        #: The canonical JSON of the data the scan was built from
        #: (`malcolm.scan.scan_points` sets it), None if unknown: two scans
        #: with the same content are the same points, so a check of one
        #: holds for the other (the layers of a configure check a scan once)
        self.content: str | None = None

    def copy(self) -> ScanPoints:
        """The same scan, sharing this one's dimensions (and `content`) but
        none of the whole-scan arrays it may have kept."""
        same = ScanPoints(self._dims, self._duration)
        same.content = self.content
        return same

    def __repr__(self) -> str:
        return f"<ScanPoints axes={self.axes} shape={self.shape}>"

    @property
    def size(self) -> int:
        """Total number of points."""
        return self._size

    @property
    def has_duration(self) -> bool:
        """Whether the scan says how long each point takes."""
        return self._timed

    # ---- points of some steps

    def _check_range(self, start: int, stop: int) -> tuple[int, int]:
        start, stop = _integer("start", start), _integer("stop", stop)
        if not 0 <= start <= stop <= self._size:
            raise IndexError(
                f"steps {start} to {stop} are not a range of the {self._size} points"
            )
        return start, stop

    def _axes(self, axes: Sequence[str] | None) -> list[str]:
        if axes is None:
            return list(self.axes)
        if isinstance(axes, str):
            raise TypeError("axes must be a sequence of axis names, not a str")
        for axis in axes:
            if axis not in self.axes:
                raise KeyError(f"{axis!r} is not an axis of this scan {self.axes}")
        return [a for a in self.axes if a in axes]

    def _evaluate(
        self, steps: np.ndarray, axes: list[str], bounds: bool, duration: bool
    ) -> tuple[Arrays, Arrays, Arrays, np.ndarray | None]:
        """Positions (and bounds, and durations, if asked) at ``steps``."""
        durations = None
        if duration and self._duration is not None:
            durations = np.full(len(steps), self._duration)
        if self._size == 0:
            empty = np.zeros(0)
            return (
                {a: empty for a in axes},
                {a: empty for a in axes} if bounds else {},
                {a: empty for a in axes} if bounds else {},
                empty if duration and self._timed else None,
            )
        positions, lower, upper, timed = stack_points(
            self._dims, steps, axes, bounds, duration
        )
        durations = timed if timed is not None else durations
        order = [a for a in self.axes if a in positions]
        return (
            {a: positions[a] for a in order},
            {a: lower[a] for a in order if a in lower},
            {a: upper[a] for a in order if a in upper},
            durations,
        )

    def chunk(self, start: int, stop: int, axes: Sequence[str] | None = None) -> Chunk:
        """Positions, bounds and durations of the steps ``start .. stop-1``.

        Args:
            start: The first step (0 .. size).
            stop: One past the last step (start .. size).
            axes: Only these axes (default every axis).

        Raises:
            IndexError: if ``start .. stop`` is not within the scan.
            KeyError: naming an axis the scan does not have.
        """
        start, stop = self._check_range(start, stop)
        names = self._axes(axes)
        positions, lower, upper, duration = self._evaluate(
            np.arange(start, stop), names, bounds=True, duration=True
        )
        return Chunk(
            start,
            stop,
            _read_only(positions),
            _read_only(lower),
            _read_only(upper),
            None if duration is None else _frozen(duration),
        )

    def chunks(
        self,
        chunk_size: int = CHUNK_SIZE,
        start: int = 0,
        stop: int | None = None,
        axes: Sequence[str] | None = None,
    ) -> Iterator[Chunk]:
        """The steps ``start .. stop-1`` (default: the whole scan) as chunks of
        at most ``chunk_size`` steps.

        Raises:
            IndexError, KeyError: as `chunk`, when called.
            ValueError: if ``chunk_size`` is not a positive integer.
        """
        start, stop = self._check_range(start, self._size if stop is None else stop)
        size = _chunk_size(chunk_size)
        names = self._axes(axes)
        return (
            self.chunk(first, min(stop, first + size), names)
            for first in range(start, stop, size)
        )

    def _step(self, index: int) -> int:
        index = _integer("index", index)
        if not -self._size <= index < self._size:
            raise IndexError(f"point {index} is out of range for {self._size} points")
        return index % self._size

    def point(self, index: int) -> dict[str, float]:
        """The position of every axis at point ``index`` (negative counts from
        the end)."""
        step = np.array([self._step(index)])
        positions, _, _, _ = self._evaluate(step, self.axes, False, False)
        return {axis: float(positions[axis][0]) for axis in self.axes}

    def position(self, axis: str, index: int) -> float:
        """The position of ``axis`` at point ``index``."""
        names = self._axes([axis])
        step = np.array([self._step(index)])
        positions, _, _, _ = self._evaluate(step, names, False, False)
        return float(positions[axis][0])

    def duration_at(self, index: int) -> float | None:
        """Seconds at point ``index``, or None if the scan does not say."""
        step = np.array([self._step(index)])
        _, _, _, duration = self._evaluate(step, [], False, True)
        return None if duration is None else float(duration[0])

    # ---- whole-scan arrays (memory-hungry)

    def _whole(self, kind: str) -> Any:
        """A whole-scan array per axis (or of durations), filled a chunk at a
        time and kept."""
        if kind not in self._full:
            axes: list[str | None] = [None] if kind == "duration" else list(self.axes)
            if kind == "duration" and not self._timed:
                self._full[kind] = None
                return None
            whole: dict[str | None, np.ndarray] = {}
            for axis in axes:
                values = np.empty(self._size)
                first = 0
                for piece in self.column(kind, axis):
                    values[first : first + len(piece)] = piece
                    first += len(piece)
                values.flags.writeable = False
                whole[axis] = values
            self._full[kind] = whole[None] if kind == "duration" else whole
        return self._full[kind]

    @property
    def positions(self) -> Arrays:
        """Per axis, its demand position at every point (memory-hungry: a
        whole-scan array per axis, kept once computed)."""
        return self._whole("positions")

    @property
    def lower(self) -> Arrays:
        """Per axis, its position at the start of every point (for fly
        scanning; equal to the position for axes that do not fly).
        Memory-hungry, as `positions`."""
        return self._whole("lower")

    @property
    def upper(self) -> Arrays:
        """Per axis, its position at the end of every point. Memory-hungry, as
        `positions`."""
        return self._whole("upper")

    @property
    def duration(self) -> np.ndarray | None:
        """Seconds per point for every point, or None if the scan does not
        say. Memory-hungry, as `positions`; see `duration_at`."""
        return self._whole("duration")

    # ---- runs

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

    # ---- JSON

    def to_json(self) -> dict[str, Any]:
        """A JSON-ready dict: ``axes``, ``size``, ``shape``, and per axis lists of
        ``positions``, ``lower``, ``upper``, plus ``duration`` (a list or
        None). Memory-hungry: every point as Python floats; `iter_json` gives
        the same document as text, a chunk at a time."""

        def column(kind: str, axis: str | None) -> list[float]:
            return [v for piece in self.column(kind, axis) for v in piece.tolist()]

        return {
            "axes": list(self.axes),
            "size": self.size,
            "shape": list(self.shape),
            **{
                kind: {a: column(kind, a) for a in self.axes}
                for kind in ("positions", "lower", "upper")
            },
            "duration": column("duration", None) if self.has_duration else None,
        }

    def column(
        self, kind: str, axis: str | None = None, chunk_size: int = CHUNK_SIZE
    ) -> Iterator[np.ndarray]:
        """One axis's ``positions``, ``lower`` or ``upper`` values (or, for kind
        ``duration`` and no axis, the durations), a chunk of at most
        ``chunk_size`` steps at a time, from the first step to the last.

        Raises:
            KeyError: for an axis the scan does not have.
            ValueError: for an unknown kind, or durations of a scan without.
        """
        if kind == "duration":
            if axis is not None:
                raise ValueError("durations are of the scan, not of an axis")
            if not self._timed:
                raise ValueError("this scan does not say how long its points take")
            axes: list[str] = []
        elif kind in ("positions", "lower", "upper"):
            if axis is None:
                raise ValueError(f"{kind} are of an axis: name one")
            axes = self._axes([axis])
        else:
            raise ValueError(
                f"unknown kind {kind!r}: expected positions, lower, upper or duration"
            )
        return self._column(kind, axes, _chunk_size(chunk_size))

    def _column(
        self, kind: str, axes: list[str], chunk_size: int
    ) -> Iterator[np.ndarray]:
        for first in range(0, self._size, chunk_size):
            steps = np.arange(first, min(self._size, first + chunk_size))
            positions, lower, upper, duration = self._evaluate(
                steps, axes, bounds=kind in ("lower", "upper"), duration=not axes
            )
            if not axes:
                assert duration is not None
                yield duration
            else:
                yield {"positions": positions, "lower": lower, "upper": upper}[kind][
                    axes[0]
                ]

    def iter_json(self, chunk_size: int = CHUNK_SIZE) -> Iterator[str]:
        """The text of ``json.dumps(self.to_json())``, in pieces, computing at
        most ``chunk_size`` points at a time: memory stays bounded whatever
        the size of the scan.

        Raises:
            ValueError: if ``chunk_size`` is not a positive integer; while
                iterating, if a value is not finite (cannot be JSON).
        """
        from .jsonout import iter_json

        return iter_json(self, _chunk_size(chunk_size))

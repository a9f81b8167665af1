"""Excluders (a ROIExcluder's regions on two axes) and the points they keep.

Which points of a dimension a region keeps cannot be known without looking
at each one, so a dimension with an excluder is evaluated once, when the
scan is built, in chunks of `CHUNK` points. What is kept is held as runs of
consecutive unrolled indexes (`KeptRuns`): a convex region over a grid keeps
one or two runs per row, so the memory grows with the number of rows, not
with the number of points.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from .errors import GeneratorError
from .fields import Fields
from .generators import Arrays
from .rois import ROI, parse_roi

ROI_EXCLUDER_TYPEID = "scanpointgenerator:excluder/ROIExcluder:1.0"

#: Points evaluated at a time when looking for the points a region keeps
CHUNK = 1 << 16


@dataclass
class Excluder:
    """A parsed ROIExcluder: keeps the points inside any of its ROIs."""

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


def parse_excluder(data: Any, path: str) -> Excluder:
    """Parse one excluder dict found at ``path`` of the input."""
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
    return Excluder(path, axes, rois)


class KeptRuns:
    """The unrolled indexes a dimension keeps, as runs of consecutive ones.

    Args:
        starts: The first unrolled index of each run, increasing.
        stops: One past the last unrolled index of each run.
    """

    def __init__(self, starts: np.ndarray, stops: np.ndarray) -> None:
        self.starts = starts.astype(np.int64)
        #: kept index of the first point of each run, then the number kept
        self.offsets = np.concatenate(([0], np.cumsum(stops - starts)))

    @property
    def size(self) -> int:
        """Number of points kept."""
        return int(self.offsets[-1])

    def unrolled(self, index: np.ndarray) -> np.ndarray:
        """The unrolled index of each kept ``index`` (0 .. size-1)."""
        run = np.searchsorted(self.offsets, index, side="right") - 1
        return self.starts[run] + (index - self.offsets[run])


def find_runs(
    full: int, keep: Callable[[np.ndarray], np.ndarray], chunk: int | None = None
) -> KeptRuns:
    """Evaluate ``keep`` (unrolled indexes -> bool) over ``0 .. full-1`` a chunk
    (default `CHUNK`) at a time and return the runs of kept indexes."""
    chunk = chunk or CHUNK
    starts: list[np.ndarray] = []
    stops: list[np.ndarray] = []
    for first in range(0, full, chunk):
        last = min(full, first + chunk)
        kept = keep(np.arange(first, last))
        edges = np.diff(np.concatenate(([0], kept.astype(np.int8), [0])))
        starts.append(np.flatnonzero(edges == 1) + first)
        stops.append(np.flatnonzero(edges == -1) + first)
    start = np.concatenate(starts)
    stop = np.concatenate(stops)
    if not len(start):
        return KeptRuns(start, stop)
    # a run cut by a chunk boundary is one run
    joined = stop[:-1] == start[1:]
    return KeptRuns(
        start[np.concatenate(([True], ~joined))],
        stop[np.concatenate((~joined, [True]))],
    )

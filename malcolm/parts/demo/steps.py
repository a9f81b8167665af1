"""The steps of a run, as the simulated parts walk them: a chunk at a time.

A run may be a whole 100-million-point scan; its positions and durations are
computed ``CHUNK`` steps at a time (``ScanPoints.chunks``), each chunk on the
loop in well under a millisecond, never as whole-scan arrays.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

#: steps computed at a time
CHUNK = 1000


def run_steps(
    points: Any, start: int, stop: int, axis: str | None = None
) -> Iterator[tuple[int, float | None, float | None]]:
    """``(step, position of axis or None, duration or None)`` for the steps
    ``start .. stop-1`` of ``points`` (a ``ScanPoints``); the position is None
    when ``axis`` is None or not an axis of the scan."""
    axes = [axis] if axis is not None and axis in points.axes else []
    for chunk in points.chunks(CHUNK, start, stop, axes):
        positions = chunk.positions[axes[0]] if axes else None
        durations = chunk.duration
        for i in range(len(chunk)):
            yield (
                chunk.start + i,
                None if positions is None else float(positions[i]),
                None if durations is None else float(durations[i]),
            )

"""A scan's points as one JSON document, written a chunk at a time.

The document is the one ``json.dumps(points.to_json())`` gives, byte for
byte, so a reader cannot tell; but only one chunk of one axis is ever
computed and formatted at a time, so ``malcolm points`` on a 100-million-point
scan needs no more memory than on a small one.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .points import ScanPoints


def _values(pieces: Iterator[np.ndarray]) -> Iterator[str]:
    """A JSON list of the floats in ``pieces`` (numpy arrays), in parts."""
    yield "["
    first = True
    for piece in pieces:
        text = json.dumps(piece.tolist(), allow_nan=False)[1:-1]
        if text:
            yield text if first else ", " + text
            first = False
    yield "]"


def iter_json(points: ScanPoints, chunk_size: int) -> Iterator[str]:
    """The text of ``json.dumps(points.to_json())``, in parts.

    Raises:
        ValueError: if a value is not finite (it cannot be JSON).
    """
    yield (
        f'{{"axes": {json.dumps(points.axes)}, "size": {points.size}, '
        f'"shape": {json.dumps(points.shape)}'
    )
    for kind in ("positions", "lower", "upper"):
        yield f', "{kind}": {{'
        for i, axis in enumerate(points.axes):
            yield f"{', ' if i else ''}{json.dumps(axis)}: "
            yield from _values(points.column(kind, axis, chunk_size))
        yield "}"
    yield ', "duration": '
    if points.has_duration:
        yield from _values(points.column("duration", None, chunk_size))
    else:
        yield "null"
    yield "}"

"""`scan_points`: one entry point for every way of describing a scan as data."""

from __future__ import annotations

import json
import os
import threading
from collections import OrderedDict
from collections.abc import Mapping
from typing import Any

import numpy as np

from .compound import compound_points
from .errors import GeneratorError
from .fields import describe
from .planned import planned_points
from .points import ScanPoints
from .spec import deserialize_spec, is_spec, spec_points

#: How many scans built from data `scan_points` keeps, by their content
CACHE_SIZE = 4


class _Built:
    """The last few scans built from data, by content, so that validating a
    configure's generator and then preparing it builds it once. What is kept
    is each scan's dimensions (`ScanPoints.copy`), never whole-scan arrays."""

    def __init__(self, size: int) -> None:
        self._size = size
        self._scans: OrderedDict[str, ScanPoints] = OrderedDict()
        self._lock = threading.Lock()

    @staticmethod
    def key(data: Any) -> str | None:
        """The content of ``data`` as canonical JSON, or None if it is not
        plain JSON data (then it is not kept)."""
        try:
            return json.dumps(data, sort_keys=True)
        except (TypeError, ValueError, RecursionError):
            return None

    def get(self, key: str) -> ScanPoints | None:
        with self._lock:
            points = self._scans.get(key)
            if points is not None:
                self._scans.move_to_end(key)
        return None if points is None else points.copy()

    def clear(self) -> None:
        with self._lock:
            self._scans.clear()

    def put(self, key: str, points: ScanPoints) -> None:
        with self._lock:
            self._scans[key] = points.copy()
            while len(self._scans) > self._size:
                self._scans.popitem(last=False)


_built = _Built(CACHE_SIZE)


def forget_built_scans() -> None:
    """Forget the scans `scan_points` keeps, so the next call builds afresh
    (for benchmarks and tests)."""
    _built.clear()


def points_from_data(data: Any) -> ScanPoints:
    """Scan points of a decoded dict: a CompoundGenerator (it has a ``typeid``)
    or a serialized scanspec Spec (it has a ``type``). A mapping whose only key
    is ``generator`` (as in a configure call) is unwrapped first."""
    path = ""
    if (
        isinstance(data, Mapping)
        and set(data) == {"generator"}
        and isinstance(data["generator"], Mapping)
    ):
        data, path = data["generator"], "generator"
    if not isinstance(data, Mapping):
        raise GeneratorError(
            path,
            "expected a mapping (a CompoundGenerator or a serialized scanspec Spec),"
            f" got {describe(data)}",
        )
    if "type" in data and "typeid" not in data:
        return spec_points(deserialize_spec(data, path), path)
    if path:
        try:
            return compound_points(data)
        except GeneratorError as e:
            where = f"{path}.{e.path}" if e.path else path
            raise GeneratorError(where, e.reason) from None
    return compound_points(data)


def scan_points(generator: Any) -> ScanPoints:
    """The points of a scan, computed when asked for (see `ScanPoints`).

    Building is cheap whatever the scan's size: the generators are parsed and
    checked, and a few values of each are looked at to refuse numbers too
    large; no point is computed, except where a region joins dimensions (its
    kept points are found once, in chunks). The last few scans built from
    data are kept by content, so the same dict given again (validate, then
    configure) is not built again; the points say what they were built from
    (`ScanPoints.content`), so a check of a scan made once need not be made
    again for the same content. The very object an operation in progress
    planned (`malcolm.scan.planned`: a manager's generator, handed to its
    children) is not read again at all. Safe to call from any thread.

    Args:
        generator: A scanspec `Spec`; a CompoundGenerator dict as GDA sends it;
            a serialized scanspec Spec (what ``Spec.serialize()`` gives); or
            `ScanPoints` already computed (returned as they are). Only data:
            text is refused, never taken as the name of a file (a caller's
            argument must not make the server read its files); read a file
            with `malcolm.scan.files.read_generator_file`.

    Raises:
        GeneratorError: naming where in the input the first problem is.
    """
    if isinstance(generator, ScanPoints):
        return generator
    planned = planned_points(generator)
    if planned is not None:  # this very object, planned by the caller's operation
        return planned.copy()
    if isinstance(generator, str | bytes | os.PathLike):
        raise GeneratorError(
            "",
            "expected a mapping (a CompoundGenerator or a serialized scanspec Spec)"
            f" or a Spec, got {_what(generator)}; a scan is given as data, never"
            " as the name of a file",
        )
    with np.errstate(all="ignore"):
        if is_spec(generator):
            return spec_points(generator)
        key = _built.key(generator)
        points = None if key is None else _built.get(key)
        if points is None:
            points = points_from_data(generator)
            points.content = key
            if key is not None:
                _built.put(key, points)
        return points


def _what(value: Any) -> str:
    """What kind of value ``value`` is, without echoing it."""
    if isinstance(value, str):
        return "text"
    if isinstance(value, bytes):
        return "bytes"
    return type(value).__name__

"""`scan_points`: one entry point for every way of describing a scan as data."""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any

import numpy as np
from scanspec.specs import Spec

from .compound import compound_points
from .errors import GeneratorError
from .fields import describe
from .points import ScanPoints
from .spec import deserialize_spec, spec_points


def _finite(points: ScanPoints) -> ScanPoints:
    """Reject a scan whose numbers overflowed (absurdly large inputs)."""
    for name in ("positions", "lower", "upper"):
        for axis, values in getattr(points, name).items():
            if not np.all(np.isfinite(values)):
                raise GeneratorError(
                    "",
                    f"{name} of axis {axis!r} are not all finite (inputs too large?)",
                )
    if points.duration is not None and not np.all(np.isfinite(points.duration)):
        raise GeneratorError("", "durations are not all finite")
    return points


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


def scan_points(generator: Spec[Any] | Mapping[str, Any] | ScanPoints) -> ScanPoints:
    """Compute every point of a scan.

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
    if isinstance(generator, str | bytes | os.PathLike):
        raise GeneratorError(
            "",
            "expected a mapping (a CompoundGenerator or a serialized scanspec Spec)"
            f" or a Spec, got {_what(generator)}; a scan is given as data, never"
            " as the name of a file",
        )
    with np.errstate(all="ignore"):
        if isinstance(generator, Spec):
            return _finite(spec_points(generator))
        return _finite(points_from_data(generator))


def _what(value: Any) -> str:
    """What kind of value ``value`` is, without echoing it."""
    if isinstance(value, str):
        return "text"
    if isinstance(value, bytes):
        return "bytes"
    return type(value).__name__

"""`scan_points`: one entry point for every way of describing a scan."""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from scanspec.specs import Spec

from .compound import compound_points
from .errors import GeneratorError
from .fields import describe
from .points import ScanPoints
from .spec import deserialize_spec, spec_points


def read_file(path: str | os.PathLike[str]) -> Any:
    """Parse a JSON (``.json``) or YAML (anything else) file.

    Raises:
        GeneratorError: if the file cannot be read or parsed.
    """
    file = Path(path)
    try:
        text = file.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        reason = e.strerror if isinstance(e, OSError) and e.strerror else str(e)
        raise GeneratorError("", f"cannot read file: {reason}") from None
    if file.suffix.lower() == ".json":
        try:
            return json.loads(text)
        except json.JSONDecodeError as e:
            raise GeneratorError("", f"invalid JSON: {e}") from None
        except RecursionError:
            raise GeneratorError("", "the document is nested too deeply") from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as e:
        raise GeneratorError("", "invalid YAML: " + " ".join(str(e).split())) from None
    except RecursionError:
        raise GeneratorError("", "the document is nested too deeply") from None


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


def scan_points(
    generator: Spec[Any] | Mapping[str, Any] | str | os.PathLike[str],
) -> ScanPoints:
    """Compute every point of a scan.

    Args:
        generator: A scanspec `Spec`; a CompoundGenerator dict as GDA sends it;
            a serialized scanspec Spec (what ``Spec.serialize()`` gives); or the
            path of a JSON (``.json``) or YAML file holding either dict.

    Raises:
        GeneratorError: naming where in the input the first problem is.
    """
    with np.errstate(all="ignore"):
        if isinstance(generator, Spec):
            return _finite(spec_points(generator))
        if isinstance(generator, str | os.PathLike):
            return _finite(points_from_data(read_file(generator)))
        return _finite(points_from_data(generator))

"""Scan points from a scanspec Spec or a scanpointgenerator CompoundGenerator.

`scan_points` accepts any of the ways a scan can be described as data and
returns a `ScanPoints`, which computes the points of the steps asked for
(`ScanPoints.chunk`), a chunk at a time, with memory in proportion to the
sizes of the scan's dimensions, not of the scan. It never reads a file:
`read_generator_file` (used by ``malcolm points``) does that, kept apart so
that no caller's argument names a file on the server.

The names below are loaded when first used, so ``from malcolm.scan import
gda`` costs nothing, and scanspec (half a second to import) is imported only
when a Spec is used.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .cost import build_cost, cheap_to_build
    from .errors import GeneratorError
    from .files import read_generator_file
    from .load import scan_points
    from .points import Chunk, Dimension, ScanPoints

__all__ = [
    "Chunk",
    "Dimension",
    "GeneratorError",
    "ScanPoints",
    "build_cost",
    "cheap_to_build",
    "read_generator_file",
    "scan_points",
]

_WHERE = {
    "Chunk": "points",
    "Dimension": "points",
    "GeneratorError": "errors",
    "ScanPoints": "points",
    "build_cost": "cost",
    "cheap_to_build": "cost",
    "read_generator_file": "files",
    "scan_points": "load",
}


def __getattr__(name: str) -> Any:
    if name not in _WHERE:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(import_module(f".{_WHERE[name]}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))

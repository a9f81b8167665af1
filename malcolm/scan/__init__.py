"""Scan points from a scanspec Spec or a scanpointgenerator CompoundGenerator.

`scan_points` accepts any of the ways a scan can be described as data and
returns a `ScanPoints` holding every point's positions, bounds and duration.
It never reads a file: `read_generator_file` (used by ``malcolm points``)
does that, kept apart so that no caller's argument names a file on the
server.
"""

from .errors import GeneratorError
from .files import read_generator_file
from .load import scan_points
from .points import Dimension, ScanPoints

__all__ = [
    "Dimension",
    "GeneratorError",
    "ScanPoints",
    "read_generator_file",
    "scan_points",
]

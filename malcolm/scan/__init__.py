"""Scan points from a scanspec Spec or a scanpointgenerator CompoundGenerator.

`scan_points` accepts any of the ways a scan can be described and returns a
`ScanPoints` holding every point's positions, bounds and duration.
"""

from .errors import GeneratorError
from .load import scan_points
from .points import Dimension, ScanPoints

__all__ = ["Dimension", "GeneratorError", "ScanPoints", "scan_points"]

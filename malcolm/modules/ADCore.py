"""areaDetector (ADCore) block types that parts can declare they control."""

from malcolm.sim.position_plugin import PositionPlugin

__all__ = ["PositionPlugin"]

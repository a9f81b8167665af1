"""Build CompoundGenerator dicts as GDA sends them (for scripts, demos, tests)."""

from __future__ import annotations

from typing import Any

PREFIX = "scanpointgenerator:generator/"


def line(
    axis: str,
    size: int,
    start: float = 0.0,
    stop: float = 1.0,
    alternate: bool = False,
    units: str = "mm",
) -> dict[str, Any]:
    """A LineGenerator dict: ``size`` points from ``start`` to ``stop``."""
    return {
        "typeid": f"{PREFIX}LineGenerator:1.0",
        "axes": [axis],
        "units": [units],
        "start": [start],
        "stop": [stop],
        "size": size,
        "alternate": alternate,
    }


def spiral(
    x: str,
    y: str,
    radius: float,
    scale: float = 1.0,
    centre: tuple[float, float] = (0.0, 0.0),
    alternate: bool = False,
    units: str = "mm",
) -> dict[str, Any]:
    """A SpiralGenerator dict: out from ``centre`` to ``radius``, rings
    ``scale`` apart (about ``pi * (radius / scale) ** 2`` points)."""
    return {
        "typeid": f"{PREFIX}SpiralGenerator:1.0",
        "axes": [x, y],
        "units": [units, units],
        "centre": list(centre),
        "radius": radius,
        "scale": scale,
        "alternate": alternate,
    }


def compound(*generators: dict[str, Any], duration: float = 0.0) -> dict[str, Any]:
    """A CompoundGenerator dict of ``generators``, outermost first."""
    return {
        "typeid": f"{PREFIX}CompoundGenerator:1.0",
        "generators": list(generators),
        "excluders": [],
        "mutators": [],
        "duration": duration,
        "continuous": True,
        "delay_after": 0.0,
    }

"""A simulated beamline IOC (softioc), run as a subprocess (docs/ca.md).

``malcolm sim-ioc --prefix P`` (or ``python -m malcolm.sim.beamline_ioc``)
serves, under ``P``, an areaDetector driver with a position plugin and an
HDF5 writer (:mod:`.detector`), two motors and a trajectory-scan controller
(:mod:`.motion`). :class:`~.runner.SimIOC` starts one from Python (tests,
benchmarks).
"""

from .runner import SimIOC, ca_environment

__all__ = ["SimIOC", "ca_environment"]

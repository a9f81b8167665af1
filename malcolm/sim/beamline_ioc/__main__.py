"""``python -m malcolm.sim.beamline_ioc --prefix P``."""

from .cli import main

main()

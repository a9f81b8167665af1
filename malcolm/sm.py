"""Alias of :mod:`malcolm.fsm` under the name the design document imports."""

from malcolm.fsm import *  # noqa: F403
from malcolm.fsm import __all__  # noqa: F401

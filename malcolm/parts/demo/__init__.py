"""Simulated parts for the demo and the tests: no hardware needed."""

from .counter import CounterPart
from .detector import SimDetectorPart
from .hello import HelloPart
from .motor import SimMotorPart
from .scan import MotorMovePart, RunnableChildPart

__all__ = [
    "CounterPart",
    "HelloPart",
    "MotorMovePart",
    "RunnableChildPart",
    "SimDetectorPart",
    "SimMotorPart",
]

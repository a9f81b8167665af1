"""A manager over three children wired as a PandA's are: each child has an
output port (a field tagged ``sourcePort:bool:<CHILD>.OUT``) and an input
mux (``INP``, a choice of the outputs tagged ``sinkPort:bool:ZERO``)."""

from __future__ import annotations

from malcolm.controllers.manager import ManagerController
from malcolm.controllers.stateful import StatefulController
from malcolm.core import BooleanMeta, ChoiceMeta, Process
from malcolm.parts.base import ChildPart, Part, PartRegistrar

CHILDREN = ("GATE", "PULSE", "PCAP")
OUTPUTS = ["ZERO", *(f"{c}.OUT" for c in CHILDREN)]


class PortsPart(Part):
    """An output ``OUT`` and an input mux ``INP`` selecting another's output."""

    def __init__(self, name: str, child: str) -> None:
        super().__init__(name)
        self.child = child

    def setup(self, registrar: PartRegistrar) -> None:
        registrar.add_attribute(
            "INP",
            ChoiceMeta(OUTPUTS, "Input", ["sinkPort:bool:ZERO"], writeable=True),
            "ZERO",
        )
        registrar.add_attribute(
            "OUT",
            BooleanMeta("Output", [f"sourcePort:bool:{self.child}.OUT"]),
            False,
        )


def wired_process() -> Process:
    process = Process("wired")
    for child in CHILDREN:
        process.add_controller(
            StatefulController(f"BOX:{child}", [PortsPart("ports", child)])
        )
    parts = [ChildPart(child, f"BOX:{child}") for child in CHILDREN]
    process.add_controller(ManagerController("BOX", parts, "Three wired children"))
    return process

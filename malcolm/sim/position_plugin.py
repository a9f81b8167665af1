"""A soft areaDetector position plugin: tags frames with positions loaded as XML.

``xml`` puts append one position per ``<position .../>`` element to the
buffer (``positions`` counts what is left). A put of ``start=True`` begins
acquisition: one frame every ``framePeriod`` seconds (paced against fixed
deadlines, :class:`~malcolm.parts.pacing.Deadlines`) takes a position; the
put completes when the buffer has stayed empty for ``idleTime`` seconds,
which is how the real plugin's put-callback ends a run.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from malcolm.core import BooleanMeta, NumberMeta, StringMeta
from malcolm.parts.base import Part, PartRegistrar
from malcolm.parts.pacing import Deadlines

_POSITION = re.compile(r"<position\b")


@dataclass(frozen=True)
class BlockType:
    """Names a kind of block (its definition) and the fields it must have."""

    name: str
    fields: tuple[str, ...]


PositionPlugin = BlockType(
    "ADCore.PositionPlugin",
    ("delete", "idStart", "enableCallbacks", "xml", "start", "running", "positions"),
)


class SoftPositionPluginPart(Part):
    """The fields of PositionPlugin, with simulated acquisition."""

    def __init__(
        self, name: str = "plugin", frame_period: float = 0.001, idle_time: float = 0.1
    ) -> None:
        super().__init__(name)
        self.frame_period = frame_period
        self.idle_time = idle_time
        self.xml_puts = 0

    def setup(self, registrar: PartRegistrar) -> None:
        add = registrar.add_attribute
        self.delete = add(
            "delete", BooleanMeta("Clear the buffer"), put=self.put_delete
        )
        self.id_start = add(
            "idStart", NumberMeta("int32", "First uniqueId"), 1, put=self.put_id_start
        )
        self.callbacks = add(
            "enableCallbacks", BooleanMeta("Enable the plugin"), put=self.put_callbacks
        )
        self.xml = add("xml", StringMeta("Positions to load"), put=self.put_xml)
        self.start = add(
            "start", BooleanMeta("Acquire; completes at the end"), put=self.put_start
        )
        self.running = add("running", BooleanMeta("Acquiring"), False)
        self.positions = add("positions", NumberMeta("int32", "Positions left"), 0)
        self.processed = add("processed", NumberMeta("int32", "Frames tagged"), 0)

    def put_delete(self, value: bool) -> None:
        self.delete.set_value(value)
        if value:
            self.positions.set_value(0)
            self.processed.set_value(0)

    def put_id_start(self, value: int) -> None:
        self.id_start.set_value(value)

    def put_callbacks(self, value: bool) -> None:
        self.callbacks.set_value(value)

    def put_xml(self, value: str) -> None:
        self.xml.set_value(value)
        self.xml_puts += 1
        self.positions.set_value(self.positions.value + len(_POSITION.findall(value)))

    async def put_start(self, value: bool) -> None:
        self.start.set_value(value)
        if not value:
            return
        if not self.callbacks.value:
            raise RuntimeError("enableCallbacks must be set before start")
        self.running.set_value(True)
        idle = 0.0
        deadlines = Deadlines()
        try:
            while idle < self.idle_time and self.start.value:
                await deadlines.wait(self.frame_period)
                if self.positions.value > 0:
                    idle = 0.0
                    self.positions.set_value(self.positions.value - 1)
                    self.processed.set_value(self.processed.value + 1)
                else:
                    idle += self.frame_period
        finally:
            self.running.set_value(False)
            self.start.set_value(False)

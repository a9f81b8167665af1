"""ManagerController: the manager model's states (Saving, Loading) and calls.

The Editor (designs, the export, follower and fixed tables) builds on this.
"""

from __future__ import annotations

from typing import Any

from malcolm.core import ChoiceMeta, MapMeta, MethodMeta, StringMeta

from .base import Controller


class ManagerController(Controller):
    """Adds ``save(design)`` and a ``design`` attribute whose put loads."""

    model_name = "manager"

    def setup_fields(self) -> None:
        super().setup_fields()
        self.design = self._add_attr(
            "design", ChoiceMeta([""], "Design loaded", writeable=True)
        )
        self.saved: dict[str, Any] = {}

    def method_meta_save(self) -> MethodMeta:
        return MethodMeta(
            MapMeta({"design": StringMeta("Name of the design", writeable=True)}),
            description="Save the current settings as a design",
            defaults={"design": ""},
        )

    async def do_save(self, design: str = "") -> None:
        """Save the current settings as a design."""
        self.device.params = {"design": design or self.design.value}
        await self.operation("save", self._transition_and_settle("save"))

    async def put_design(self, design: str) -> None:
        self.device.params = {"design": design}
        await self.operation("load", self._transition_and_settle("load"))
        self.design.set_value(design)

"""Device: what hook functions receive as their second argument."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from malcolm.core import Attribute

if TYPE_CHECKING:
    from .base import Controller


class Device:
    """The block's live scan state and parameters, as hooks see them.

    ``device.params`` are the parameters of the configure (or validate) in
    progress, ``device.part_info[phase]`` what each part returned from a
    phase; any other name reads a parameter, else the block's attribute of
    that name (``device.completedSteps``).
    """

    def __init__(self, controller: Controller) -> None:
        self.controller = controller
        self.mri = controller.mri
        self.params: dict[str, Any] = {}
        self.part_info: dict[str, dict[str, Any]] = {}

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_"):
            raise AttributeError(name)
        params = self.__dict__.get("params", {})
        if name in params:
            return params[name]
        block = self.controller.block
        if name in block and isinstance(block[name], Attribute):
            return block[name].value
        raise AttributeError(f"{self.mri}: the device has no {name!r}")

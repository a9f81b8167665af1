"""The section kinds malcolm itself provides, registered on import.

``malcolm.config.build`` imports this module, so every kind below is known
to :func:`malcolm.config.registry.lookup` whenever blocks are built.

Controllers (``controller.X``; a block without one gets a StatefulController):

- ``controller.StatefulController``, ``controller.ManagerController``,
  ``controller.RunnableController``;
- ``controller.AreaDetectorController``: a RunnableController interpreting
  the ``area_detector_runnable_device`` model; takes the design document's
  ``design:`` key (the design to load, stored as ``initial_design``);
- ``controller.GenericScanController``: a RunnableController.

Attributes bound to soft channels (``malcolm.parts.soft``): ``ca.Double``,
``ca.Long`` (also ``ca.Int``), ``ca.String``, ``ca.LongString``, ``ca.Enum``,
``ca.Bool``, ``ca.Table`` (``columns``: name -> type).

Parts: the demo's (``parts.HelloPart``, ``parts.CounterPart``,
``parts.SimMotorPart``, ``parts.SimDetectorPart``, ``parts.RunnableChildPart``,
``parts.MotorMovePart``), ``parts.SoftPositionPluginPart``, and the design
document's ``parts.PosPluginPart``, ``parts.DriverRunPart``,
``parts.DetectorPart``, ``parts.ZebraPart``, ``parts.MotorPart``;
``parts.MotionTrajectoryPart`` (``malcolm.parts.motion_manager``: a motion
controller manager's trajectory scan).

A Zebra2 box over TCP (``malcolm.parts.zebra2_manager``,
``malcolm.parts.zebra2_capture``, ``malcolm.parts.zebra2_scan``):
``zebra2.Manager`` (children made by introspecting the box),
``zebra2.Capture`` (PCAP capture to HDF5) and ``zebra2.Scan`` (the
ZebraManager's position compare and capture, one row per scan point).

Saved-design records (``malcolm.parts.design``): ``parts.ModelPart``,
``parts.PalettePart``, ``parts.ExportPart``, ``parts.FollowerPart`` and
``fixed.Int|Float|String|Bool|Enum|Table``. They are not parts: a block
definition that uses one is an error; :func:`malcolm.parts.design.load_design`
reads them.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from malcolm.controllers.manager import ManagerController
from malcolm.controllers.runnable import RunnableController
from malcolm.controllers.stateful import StatefulController
from malcolm.parts import (
    adcore,
    motion_manager,
    soft,
    zebra2_capture,
    zebra2_manager,
    zebra2_scan,
)
from malcolm.parts import ca as ca_parts
from malcolm.parts.base import Part
from malcolm.parts.demo import (
    CounterPart,
    HelloPart,
    MotorMovePart,
    RunnableChildPart,
    SimDetectorPart,
    SimMotorPart,
)
from malcolm.parts.design import DESIGN_KINDS
from malcolm.sim.position_plugin import SoftPositionPluginPart

from .registry import register_builtin

__all__ = [
    "AreaDetectorController",
    "DEFAULT_CONTROLLER",
    "GenericScanController",
    "builtin_kinds",
]


class AreaDetectorController(RunnableController):
    """A RunnableController with the area detector's run phases."""

    def __init__(
        self,
        mri: str,
        parts: Sequence[Part] = (),
        description: str = "",
        design: str = "",
        **kwargs: Any,
    ) -> None:
        kwargs.setdefault("model", "area_detector_runnable_device")
        # the design the definition asks for: loaded at start if it exists
        kwargs.setdefault("initial_design", design)
        super().__init__(mri, parts, description, **kwargs)


class GenericScanController(RunnableController):
    """Co-ordinates Device-layer blocks through a scan (the generic case)."""


#: the controller of a block whose definition has no ``controller.X``
DEFAULT_CONTROLLER = StatefulController

_BUILTINS: dict[str, Any] = {
    "controller.StatefulController": StatefulController,
    "controller.ManagerController": ManagerController,
    "controller.RunnableController": RunnableController,
    "controller.AreaDetectorController": AreaDetectorController,
    "controller.GenericScanController": GenericScanController,
    "ca.Double": soft.CADoublePart,
    "ca.Long": soft.CALongPart,
    "ca.Int": soft.CALongPart,
    "ca.String": soft.CAStringPart,
    "ca.LongString": soft.CALongStringPart,
    "ca.Enum": soft.CAEnumPart,
    "ca.Bool": soft.CABoolPart,
    "ca.Table": soft.CATablePart,
    "ca.DoubleArray": ca_parts.CADoubleArrayPart,
    "ca.LongArray": ca_parts.CALongArrayPart,
    "ca.Action": ca_parts.CAActionPart,
    "parts.HelloPart": HelloPart,
    "parts.CounterPart": CounterPart,
    "parts.SimMotorPart": SimMotorPart,
    "parts.SimDetectorPart": SimDetectorPart,
    "parts.RunnableChildPart": RunnableChildPart,
    "parts.MotorMovePart": MotorMovePart,
    "parts.SoftPositionPluginPart": SoftPositionPluginPart,
    "parts.PosPluginPart": adcore.PosPluginPart,
    "parts.DriverRunPart": adcore.DriverRunPart,
    "parts.DetectorPart": adcore.DetectorPart,
    "parts.ZebraPart": adcore.ZebraPart,
    "parts.MotorPart": adcore.MotorPart,
    # a motion controller manager's trajectory scan (docs/devices.md)
    "parts.MotionTrajectoryPart": motion_manager.MotionTrajectoryPart,
    # a Zebra2 box over TCP (docs/zebra2.md)
    "zebra2.Manager": zebra2_manager.Zebra2ManagerPart,
    "zebra2.Capture": zebra2_capture.Zebra2CapturePart,
    "zebra2.Scan": zebra2_scan.Zebra2ScanPart,
    **DESIGN_KINDS,
}


def builtin_kinds() -> list[str]:
    """Every kind this module registers, sorted."""
    return sorted(_BUILTINS)


for _kind, _factory in _BUILTINS.items():
    register_builtin(_kind, _factory)

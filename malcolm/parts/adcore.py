"""Parts that control areaDetector (ADCore) blocks (and, re-exported from
:mod:`.coordination`, the design document's co-ordination parts).

:class:`PosPluginPart` does what the design document's example does, with
the Task API's async calls: at Configure it clears the position plugin,
sets ``idStart`` and callbacks and loads the first ``batch`` positions as
XML; before the driver starts it subscribes to ``positions`` (loading
``batch`` more whenever fewer than ``batch`` are left), puts ``start`` and
waits for ``running``; at Running it waits for the ``start`` put to complete
(the plugin's put-callback ends with the acquisition) and unsubscribes.
At Abort it unsubscribes and stops the plugin if it is running.
"""

from __future__ import annotations

from typing import Any

from malcolm.fsm import AreaDetectorRunnableDevice
from malcolm.hooks import Task
from malcolm.sim.position_plugin import PositionPlugin

from .base import ChildPart, Controls, input_mri
from .coordination import DetectorPart, MotorPart, ZebraPart

__all__ = [
    "DetectorPart",
    "DriverRunPart",
    "InputChildPart",
    "MotorPart",
    "PosPluginPart",
    "ZebraPart",
    "positions_xml",
]


def positions_xml(start: int, stop: int) -> str:
    """NDPosPlugin XML tagging frames with point indices ``start..stop-1``
    (dimension ``n``), built without a Python loop per point."""
    rows = ""
    if stop > start:
        body = '"/><position n="'.join(map(str, range(start, stop)))
        rows = f'<position n="{body}"/>'
    return (
        '<pos_layout><dimensions><dimension name="n"/></dimensions>'
        f"<positions>{rows}</positions></pos_layout>"
    )


@Controls(PositionPlugin)
class PosPluginPart(ChildPart):
    """Feeds scan positions to a PositionPlugin block, ``batch`` at a time."""

    def __init__(self, name: str, mri: str, batch: int = 100) -> None:
        super().__init__(name, mri)
        if batch < 1:
            raise ValueError(f"batch must be at least 1, not {batch}")
        self.batch = batch
        self._loaded = 0
        self._load_id: int | None = None
        self._done: Any = None

    def _generate_xml(self, start: int, num: int) -> str:
        """The NDPosPlugin XML for positions ``start`` .. ``start + num - 1``."""
        return positions_xml(start, start + num)

    def _next_xml(self, device: Any) -> str | None:
        num = min(self.batch, device.totalSteps - self._loaded)
        if num <= 0:
            return None
        xml = self._generate_xml(self._loaded, num)
        self._loaded += num
        return xml

    @AreaDetectorRunnableDevice.Configure
    async def configure(self, task: Task, device: Any) -> None:
        pos = self.child
        await task.put({pos.delete: True, pos.idStart: 1, pos.enableCallbacks: True})
        self._loaded = 0
        xml = self._next_xml(device)
        if xml is not None:
            await task.put(pos.xml, xml)

    def _load_pos(self, positions: int, task: Task, device: Any) -> Any:
        if positions < self.batch:
            xml = self._next_xml(device)
            if xml is not None:
                return task.put(self.child.xml, xml)
        return None

    @AreaDetectorRunnableDevice.PreRunPluginStart
    async def start_plugin(self, task: Task, device: Any) -> None:
        pos = self.child
        self._load_id = task.subscribe(pos.positions, self._load_pos, task, device)
        running = task.when_matches(pos.running, True)
        self._done = task.put_async(pos.start, True)
        await task.wait_all(running)

    @AreaDetectorRunnableDevice.Running
    async def running(self, task: Task, device: Any) -> None:
        try:
            await task.wait_all(self._done)
        finally:
            if self._load_id is not None:
                task.unsubscribe(self._load_id)
                self._load_id = None

    @AreaDetectorRunnableDevice.Abort
    async def abort(self, task: Task, device: Any) -> None:
        if self._load_id is not None:
            task.unsubscribe(self._load_id)
            self._load_id = None
        if self.child.running.value:
            await task.put(self.child.start, False)


class DriverRunPart(ChildPart):
    """The detector driver a manager runs (no behaviour yet).

    ``readonly`` records whether the manager may write the driver's settings.
    """

    def __init__(self, name: str, mri: str, readonly: bool = False) -> None:
        super().__init__(name, mri)
        self.readonly = bool(readonly)


class InputChildPart(ChildPart):
    """A child part whose block is named by ``input`` (or ``mri``)."""

    def __init__(
        self, name: str, input: str | None = None, mri: str | None = None
    ) -> None:
        super().__init__(name, input_mri(input, mri))

    @property
    def input(self) -> str:
        return self.mri

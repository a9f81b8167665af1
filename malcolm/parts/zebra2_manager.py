"""Zebra2ManagerPart (section ``zebra2.Manager``): a manager's children made
by introspecting a Zebra2 (PandA) box over TCP.

On the manager's Reset phase (so when the process starts, and at a reset
after a start that could not reach the box) the part connects to the box's
control port, introspects it, and makes one child block per block instance
(``<mri_prefix>:PCOMP1``, ``...:SEQ``; a StatefulController with a
:class:`~.zebra2_fields.Zebra2BlockPart`), adds them to the process, and
gives the manager a ChildPart for each, so the Editor (palette, exports,
followers, fixed rows) works on them as on any child. Then it polls
``*CHANGES?`` every ``poll_period`` seconds, which keeps the children's
attributes as the box has them.

The manager gets one attribute, ``wiring``: the mux wiring as data, a
table with a row per bit_mux/pos_mux input that is wired to an output
(``sink`` ``PCAP.TRIG``, ``source`` ``CLOCK1.OUT``, ``kind`` ``bit`` or
``pos``), what a GUI draws as the arrows between children.

When the box goes away the children's attributes get INVALID alarms and
both the children's and the manager's ``health`` say so; the poll loop
keeps trying, and the first poll after it is back sets everything again.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING, Any

from malcolm.core import (
    ChoiceArrayMeta,
    StringArrayMeta,
    TableMeta,
)
from malcolm.fsm import Stateful
from malcolm.io.zebra2 import (
    DEFAULT_CONTROL_PORT,
    DEFAULT_DATA_PORT,
    DEFAULT_TIMEOUT,
    Box,
    Change,
    Zebra2Disconnected,
)

from .base import ChildPart, Part, PartRegistrar
from .zebra2_fields import Zebra2BlockPart

if TYPE_CHECKING:
    from malcolm.controllers.base import Controller
    from malcolm.hooks import Task

__all__ = ["Zebra2ManagerPart", "wiring_meta"]

log = logging.getLogger(__name__)


def wiring_meta() -> TableMeta:
    """The manager's ``wiring`` table: sink, source, kind."""
    return TableMeta(
        {
            "sink": StringArrayMeta("Mux input (BLOCK.FIELD)"),
            "source": StringArrayMeta("Output wired to it (BLOCK.FIELD)"),
            "kind": ChoiceArrayMeta(["bit", "pos"], "bit or pos bus"),
        },
        "Which output feeds which mux input",
    )


class Zebra2ManagerPart(Part):
    """Introspects a box and makes its blocks the manager's children."""

    def __init__(
        self,
        name: str = "zebra2",
        host: str = "localhost",
        control_port: int = DEFAULT_CONTROL_PORT,
        data_port: int = DEFAULT_DATA_PORT,
        mri_prefix: str = "",
        poll_period: float = 0.1,
        timeout: float = DEFAULT_TIMEOUT,
    ) -> None:
        super().__init__(name)
        if not poll_period > 0:
            raise ValueError(f"poll_period must be > 0 s, not {poll_period}")
        self.host = host
        self.control_port = int(control_port)
        self.data_port = int(data_port)
        self.mri_prefix = mri_prefix
        self.poll_period = float(poll_period)
        self.timeout = float(timeout)
        self.box: Box | None = None
        #: instance name -> child mri, once made
        self.children: dict[str, str] = {}
        self._controller: Controller | None = None
        self._registrar: PartRegistrar | None = None
        self._muxes: dict[str, str] = {}  # sink -> kind

    def setup(self, registrar: PartRegistrar) -> None:
        self._controller = registrar.controller
        self._registrar = registrar
        self.wiring = registrar.add_attribute("wiring", wiring_meta())

    @property
    def address(self) -> str:
        return f"{self.host}:{self.control_port}"

    # ---- phases
    @Stateful.Reset
    async def reset(self, task: Task) -> None:
        """Introspect and make the children (once), then poll."""
        if self.box is None:
            box = Box(self.host, self.control_port, self.poll_period, self.timeout)
            try:
                await box.start()
            except Zebra2Disconnected:
                await box.close()
                raise
            self.box = box
            # closed with the process (Process.stop closes what is here)
            task.process.backends[f"zebra2 {self.address} {id(self)}"] = box
            await self._make_children(task, box)
            box.watch_state(self._on_state)
            box.watch_batches(self._on_batch)
            await box.poll()  # every value, before the manager is Ready
        self.box.run()

    @Stateful.Disable
    async def disable(self, task: Task) -> None:
        """Stop polling (the children stay; a reset polls again)."""
        if self.box is not None:
            await self.box.stop_polling()

    # ---- children
    async def _make_children(self, task: Task, box: Box) -> None:
        from malcolm.controllers.stateful import StatefulController

        controller = self._controller
        assert controller is not None and box.layout is not None
        process = task.process
        prefix = self.mri_prefix or controller.mri
        made = []
        for block in box.layout.blocks:
            for instance in block.instances:
                mri = f"{prefix}:{instance}"
                part = Zebra2BlockPart("fields", box, block, instance)
                child = StatefulController(mri, [part], block.description)
                made.append((instance, mri, child))
            for f in block.fields:
                if f.type in ("bit_mux", "pos_mux"):
                    for instance in block.instances:
                        self._muxes[f"{instance}.{f.name}"] = f.type[:3]
        for instance, mri, child in made:
            process.add_controller(child)
            await child.start()
            controller.add_part(ChildPart(instance, mri))
            self.children[instance] = mri
        layout = getattr(controller, "layout", None)
        if layout is not None:  # a ManagerController: its palette gets them
            rows = list(layout.meta.rows(layout.value))
            known = {row["name"] for row in rows}
            for instance, mri in self.children.items():
                if instance not in known:
                    row = {"name": instance, "mri": mri, "x": 0.0, "y": 0.0}
                    rows.append({**row, "visible": True})
            layout.set_value(layout.meta.validate(rows))

    # ---- the box's news
    def _on_state(self, connected: bool, message: str) -> None:
        assert self._registrar is not None
        if connected:
            self._registrar.report_health(None)
        else:
            self._registrar.report_health(
                f"{self.address}: {message or 'connection lost'}"
            )

    def _on_batch(self, changes: list[Change]) -> None:
        if any(
            f"{c.block}.{c.field}" in self._muxes and c.attribute is None
            for c in changes
        ):
            self._update_wiring()

    def _update_wiring(self) -> None:
        assert self._controller is not None and self._controller.process is not None
        rows: dict[str, list[Any]] = {"sink": [], "source": [], "kind": []}
        process = self._controller.process
        for sink, kind in self._muxes.items():
            instance, _, field = sink.partition(".")
            block = process.get_block(self.children[instance])
            source = block[field].value  # type: ignore[union-attr]
            if source in ("ZERO", "ONE", "", None):
                continue
            rows["sink"].append(sink)
            rows["source"].append(source)
            rows["kind"].append(kind)
        self.wiring.set_value(rows)

    def wiring_rows(self) -> list[dict[str, str]]:
        """The ``wiring`` table as rows ``{sink, source, kind}``."""
        value = self.wiring.value
        return [
            {"sink": s, "source": src, "kind": k}
            for s, src, k in zip(value["sink"], value["source"], value["kind"])
        ]

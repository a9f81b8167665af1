"""The hypothesis machine of a live manager's calls (save, load, table edits),
on top of :class:`~malcolm.conformance.machines.base.ControllerMachine`."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from hypothesis import strategies as st
from hypothesis.stateful import rule

from malcolm.core import BadValueError

from ..live import MRI
from .base import Call, ControllerMachine

EMPTY_EXPORTS = {"name": [], "source": [], "description": []}


class ManagerBase(ControllerMachine):
    """What the manager and runnable machines share: the design in
    snapshots, the manager calls for two at once."""

    DESIGNS = ("d1", "d2", "", "bad name!", "never_saved")

    def saved(self, design: str) -> bool:
        assert self.block is not None
        return (Path(self.block.tmp) / MRI / f"{design}.yaml").is_file()

    def snapshot(self) -> dict[str, Any]:
        snap = super().snapshot()
        snap["design"] = self.ctrl.design.value
        return snap

    def known_calls(self) -> list[str]:
        return [*super().known_calls(), "save", "load", "design", "exports"]

    def draw_call(self, data: st.DataObject, name: str, label: str) -> Call:
        if name in ("save", "load", "design"):
            design = data.draw(st.sampled_from(self.DESIGNS), label=f"{label} design")
            if name == "design":
                return Call(name, design, put=True)
            return Call(name, {"design": design})
        if name == "exports":
            return Call(name, EMPTY_EXPORTS, put=True)
        return super().draw_call(data, name, label)


class ManagerMachine(ManagerBase):
    """Adds save and load of designs, an edit of the exports table (which
    goes through the disabled state) and set_visible."""

    @rule(design=st.sampled_from(ManagerBase.DESIGNS))
    def save(self, design: str) -> None:
        before = self.snapshot()
        out = self.call(Call("save", {"design": design}))
        if out is None:
            return
        name = design or before["design"]
        if name in ("", "bad name!"):
            assert isinstance(out.error, BadValueError), out
            self.check_unchanged(before, "a refused save")
            return
        assert out.error is None, out
        assert self.saved(name), f"save({name!r}) wrote no file"
        self.expect_walk(before, "save")
        assert self.snapshot()["design"] == name

    @rule(design=st.sampled_from(ManagerBase.DESIGNS), put=st.booleans())
    def load(self, design: str, put: bool) -> None:
        """load(design), or a put of design (the same thing)."""
        before = self.snapshot()
        call = (
            Call("design", design, put=True)
            if put
            else Call("load", {"design": design})
        )
        out = self.call(call)
        if out is None:
            return
        if not design or not self.saved(design):
            assert isinstance(out.error, BadValueError), out
            self.check_unchanged(before, "a refused load")
            return
        assert out.error is None, out
        self.expect_walk(before, "load")
        assert self.snapshot()["design"] == design

    @rule()
    def edit_exports(self) -> None:
        """A put of the exports table: the manager goes through disabling."""
        before = self.snapshot()
        out = self.call(Call("exports", EMPTY_EXPORTS, put=True))
        if out is None:
            return
        assert out.error is None, out
        self.expect_walk(before, "disable")

    @rule(visible=st.booleans())
    def set_visible_of_no_child(self, visible: bool) -> None:
        before = self.snapshot()
        out = self.call(Call("set_visible", {"block_name": "NOPE", "visible": visible}))
        if out is None:
            return
        assert isinstance(out.error, BadValueError), out
        self.check_unchanged(before, "a refused set_visible")

"""ManagerController: a block that manages children through a design.

The Editor's fields live on the manager's own structure, where pymalcolm
clients look for them: ``design`` (put = load), ``modified``, ``layout``
(the palette), ``exports``, ``followers`` and ``model``; methods ``save``,
``load``, ``set_visible`` and ``set_position``. Each export, follower and
fixed row becomes a part (``malcolm.editor.runtime``). A followed or fixed
child attribute that changes by any other hand puts the manager in Fault,
naming it; reset writes the design's values back.
"""

from __future__ import annotations

import asyncio
import logging
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from malcolm.core import (
    Attribute,
    BadValueError,
    BooleanMeta,
    ChoiceMeta,
    MalcolmError,
    MapMeta,
    Method,
    MethodMeta,
    NumberMeta,
    StringMeta,
)
from malcolm.editor import plan, tables
from malcolm.editor.plan import (
    FIXED_KINDS,
    default_designs_dir,
    fixed_kind,
    plain_value,
)
from malcolm.editor.runtime import (
    EditorPart,
    ExportRuntime,
    FixedRuntime,
    FollowerRuntime,
)
from malcolm.editor.store import DesignStore
from malcolm.fsm import Model
from malcolm.parts.base import ChildPart
from malcolm.parts.design import Design, ExportPart, PalettePart

from .base import DEFAULT_PHASE_TIMEOUT, Controller

__all__ = [
    "FIXED_KINDS",
    "ManagerController",
    "default_designs_dir",
    "fixed_kind",
]

log = logging.getLogger(__name__)

#: states where a followed or fixed child that drifts sends the manager to Fault


def _s(name: str, description: str) -> StringMeta:
    return StringMeta(description, writeable=True)


class ManagerController(Controller):
    """Interprets the ``manager`` model and gives it an Editor."""

    model_name = "manager"

    def __init__(
        self,
        mri: str,
        parts: Sequence[Any] = (),
        description: str = "",
        designs_dir: str | Path | None = None,
        template_dirs: Sequence[str | Path] = (),
        initial_design: str = "",
        phase_timeout: float | None = DEFAULT_PHASE_TIMEOUT,
        phase_timeouts: Mapping[str, float] | None = None,
        model: Model | str | None = None,
    ) -> None:
        self.designs_dir = designs_dir
        self.template_dirs = list(template_dirs)
        self.initial_design = initial_design
        self.store: DesignStore | None = None
        self.editor_parts: list[EditorPart] = []
        self.fixed_records: list[Any] = []
        self.model_value = ""
        self.following = True
        self.background: set[asyncio.Future[Any]] = set()
        super().__init__(mri, parts, description, phase_timeout, phase_timeouts, model)
        self.layout.set_value(self._default_layout())

    # ---- fields
    def setup_fields(self) -> None:
        super().setup_fields()
        self.design = self._add_attr(
            "design", ChoiceMeta([""], "Design loaded (put to load another)")
        )
        self.modified = self._add_attr(
            "modified", BooleanMeta("Whether settings differ from the design")
        )
        self.layout = self._add_attr("layout", tables.layout_meta())
        self.exports = self._add_attr("exports", tables.exports_meta())
        self.followers = self._add_attr("followers", tables.followers_meta())
        self.model_attr = self._add_attr(
            "model", StringMeta("The model this block conforms to (metaOf)")
        )

    def method_meta_save(self) -> MethodMeta:
        return MethodMeta(
            MapMeta({"design": _s("design", "Name to save the design as")}),
            description="Save the current settings as a design",
            defaults={"design": ""},
        )

    def method_meta_load(self) -> MethodMeta:
        return MethodMeta(
            MapMeta({"design": _s("design", "Design to load")}, ["design"]),
            description="Load a design",
        )

    def method_meta_set_visible(self) -> MethodMeta:
        return MethodMeta(
            MapMeta(
                {
                    "block_name": _s("block_name", "Child name"),
                    "visible": BooleanMeta("Active or not", writeable=True),
                },
                ["block_name", "visible"],
            ),
            description="Show (activate) or hide a child; the manager is disabled",
        )

    def method_meta_set_position(self) -> MethodMeta:
        return MethodMeta(
            MapMeta(
                {
                    "block_name": _s("block_name", "Child name"),
                    "x": NumberMeta("float64", "X", writeable=True),
                    "y": NumberMeta("float64", "Y", writeable=True),
                },
                ["block_name", "x", "y"],
            ),
            description="Move a child on the canvas",
        )

    # ---- children
    @property
    def children(self) -> dict[str, str]:
        """Child name -> mri, from the manager's child parts."""
        return {
            name: part.mri
            for name, part in self.parts.items()
            if isinstance(part, ChildPart)
        }

    def resolve(self, dotted: str) -> tuple[str, str]:
        """``CHILD.FIELD`` -> (child mri, field), or BadValueError."""
        child, sep, field = str(dotted).partition(".")
        if not sep or not child or not field:
            raise BadValueError(f"{self.mri}: {dotted!r} is not CHILD.FIELD")
        mri = self.children.get(child)
        if mri is None:
            known = ", ".join(self.children) or "none"
            raise BadValueError(
                f"{self.mri}: {dotted!r} names child {child!r}, which it does not"
                f" have (children: {known})"
            )
        self.child_field(mri, field, dotted)
        return mri, field

    def child_field(self, mri: str, field: str, dotted: str = "") -> Attribute | Method:
        assert self.process is not None, f"{self.mri} is not in a process"
        block = self.process.get_block(mri)
        if field not in block:
            raise BadValueError(
                f"{self.mri}: {dotted or mri + '.' + field!r} names field {field!r},"
                f" which {mri} does not have"
            )
        return block[field]  # type: ignore[return-value]

    def _default_layout(self) -> dict[str, Any]:
        return tables.columns(
            self.layout.meta,
            [
                {"name": n, "mri": m, "x": 0.0, "y": 0.0, "visible": True}
                for n, m in self.children.items()
            ],
        )

    # ---- lifecycle
    async def start(self) -> None:
        assert self.process is not None
        base = self.designs_dir or getattr(self.process, "designs_dir", None)
        self.store = DesignStore(
            self.mri, base or default_designs_dir(), self.template_dirs
        )
        self.layout.set_value(self._default_layout())
        self._refresh_choices()
        await super().start()
        if self.initial_design:
            if self.initial_design not in self.store.names():
                # nothing saved under that name yet: normal on a new beamline
                log.warning(
                    "%s: initial design %r not found in %s; starting without one",
                    self.mri,
                    self.initial_design,
                    self.store.dir,
                )
                return
            try:
                await self.put("design", self.initial_design)
            except Exception as e:
                await self.go_fault(e)

    async def stop(self) -> None:
        for part in self.editor_parts:
            part.detach()
        for fut in list(self.background):
            fut.cancel()
        await super().stop()

    def _refresh_choices(self) -> None:
        assert self.store is not None
        choices = ["", *self.store.names()]
        if tuple(choices) != self.design.meta.choices:
            self.design.meta.choices = tuple(choices)
            self.block.notify([[["design", "meta", "choices"], choices]])

    # ---- drift: Fault exactly when a followed or fixed child differs
    def verify(self, part: EditorPart) -> None:
        if part.pending or self.current in self.model.states_tagged("quiet"):
            return
        if part not in self.editor_parts:
            return
        message = part.mismatch()
        if message:
            self.fault_now(message)

    def verify_all(self) -> None:
        for part in list(self.editor_parts):
            self.verify(part)

    def fault_now(self, message: str) -> None:
        if self.model.is_state(self.current, "fault"):
            return
        for task in self.tasks.values():
            task.stop()
        from malcolm.core import Alarm

        self._fault_message = f"{self.mri}: {message}"
        self.health.set_value(self._fault_message, alarm=Alarm.major(message))
        if self.model.transitions_for("fault", self.current):
            op = self._op
            inside = op is not None and op is asyncio.current_task()
            self.cancel_now()  # everything but the operation doing the check
            self.move("fault")
            if inside:
                # found by the operation's own check: its caller gets the reason
                raise MalcolmError(f"{self.mri}: {message}")

    def move(self, trigger: str, dest: str | None = None) -> None:
        super().move(trigger, dest)
        if self.current not in self.model.states_tagged("quiet") and trigger == "done":
            self.verify_all()

    # ---- the design as parts
    def _of(self, cls: type) -> list[Any]:
        return [p for p in self.editor_parts if isinstance(p, cls)]

    def _install(self, parts: list[EditorPart]) -> None:
        # detach every old part before removing any: removing an export
        # deletes its field, which a follower still subscribed would follow
        for old in self.editor_parts:
            old.detach()
        for old in self.editor_parts:
            self.remove_part(old.name)
        self.editor_parts = []
        for part in parts:
            self.add_part(part)
            self.editor_parts.append(part)
        for part in parts:
            part.attach()
        self.exports.set_value(
            [
                {"name": p.field, "source": p.source, "description": p.description}
                for p in self._of(ExportRuntime)
            ]
        )
        self.followers.set_value(
            [{"name": p.target, "source": p.source} for p in self._of(FollowerRuntime)]
        )
        self.fixed_records = [
            FIXED_KINDS[p.kind](p.target, plain_value(p.value, p.kind))
            for p in self._of(FixedRuntime)
        ]

    def _apply_layout(self, palette: list[PalettePart]) -> None:
        # a child the palette leaves out is where a new manager has it, so a
        # design loads the same whatever was loaded before
        current = {r["name"]: r for r in tables.rows(self._default_layout())}
        for row in palette:
            current[row.name].update(x=row.xcoord, y=row.ycoord, visible=row.visible)
        self._set_layout(list(current.values()))

    def _set_layout(self, layout_rows: list[dict[str, Any]]) -> None:
        self.layout.set_value(layout_rows)
        self.inactive = {r["name"] for r in layout_rows if not r["visible"]}

    def check_design(self, design: Design) -> list[EditorPart]:
        """Every problem of a design for this manager, before anything changes."""
        return plan.check_design(self, design)

    def design_records(self) -> list[Any]:
        """What ``save`` writes: model, palette, exports, followers, fixed."""
        return plan.design_records(self)

    # ---- load / save / edits
    async def do_load(self, design: str) -> None:
        """Load a design (same as a put of ``design``)."""
        await self.put("design", design)

    async def put(self, name: str, value: Any) -> None:
        if name == "design" and self.store is not None:
            self._refresh_choices()  # a design saved by another hand is loadable
        await super().put(name, value)

    async def put_design(self, name: str) -> None:
        if not name:
            raise BadValueError(f"{self.mri}.design: name a design to load")
        assert self.store is not None
        design = self.store.load(name)  # ConfigError / BadValueError: nothing changed
        parts = self.check_design(design)

        async def load() -> None:
            await self.fire("load")
            self._install(parts)
            self._apply_layout(design.palette)
            for part in parts:
                if isinstance(part, FixedRuntime | FollowerRuntime):
                    await part.apply()
            self.model_value = design.model or ""
            self.model_attr.set_value(self.model_value)
            self._set_meta_of(self.model_value)
            self._refresh_choices()
            self.design.set_value(name)
            self.modified.set_value(False)
            await self.settle()

        await self.operation("load", load())

    def _set_meta_of(self, model: str) -> None:
        tags = [t for t in self.block.meta.tags if not t.startswith("metaOf:")]
        if model:
            tags.append(f"metaOf:{model}")
        self.block.meta.tags = tuple(tags)
        self.block.notify([[["meta", "tags"], tags]])

    async def do_save(self, design: str = "") -> None:
        """Save the current settings as a design (default: the loaded one)."""
        name = design or self.design.value
        if not name:
            raise BadValueError(f"{self.mri}.save: name the design to save")
        assert self.store is not None
        self.store.check_writable(name)  # refused before the manager leaves Ready

        async def save() -> None:
            await self.fire("save")
            records = self.design_records()
            self.store.save(name, records)
            fixed = [r for r in records if type(r) in FIXED_KINDS.values()]
            self._install(
                plan.build_parts(self, plan.records_from_tables(self) + fixed)
            )
            self._refresh_choices()
            self.design.set_value(name)
            self.modified.set_value(False)
            await self.settle()

        await self.operation("save", save())

    async def _edit_tables(self, exports=None, followers=None, layout=None) -> None:
        """Change the tables: the manager goes to Disabled with the new parts."""
        records = plan.records_from_tables(self, exports, followers)
        # an attribute now exported or followed is no longer fixed
        moving = {r.source if isinstance(r, ExportPart) else r.name for r in records}
        records += [r for r in self.fixed_records if r.name not in moving]
        parts = plan.build_parts(self, records)  # problems raised before any change

        async def reload() -> None:
            await self.fire("disable")
            self._install(parts)
            if layout is not None:
                self._set_layout(layout)
            self.modified.set_value(True)
            await self.settle()

        await self.operation("disable", reload())

    async def put_exports(self, value: dict[str, Any]) -> None:
        await self._edit_tables(exports=tables.rows(value))

    async def put_followers(self, value: dict[str, Any]) -> None:
        await self._edit_tables(followers=tables.rows(value))

    async def put_layout(self, value: dict[str, Any]) -> None:
        new = tables.rows(value)
        old = tables.rows(self.layout.value)
        if [r["name"] for r in new] != [r["name"] for r in old] or [
            r["mri"] for r in new
        ] != [r["mri"] for r in old]:
            raise BadValueError(
                f"{self.mri}.layout: the names and mris of the children cannot change"
            )
        if not all(math.isfinite(r[xy]) for r in new for xy in ("x", "y")):
            raise BadValueError(f"{self.mri}.layout: positions must be finite numbers")
        if [r["visible"] for r in new] != [r["visible"] for r in old]:
            await self._edit_tables(layout=new)
        else:
            self._set_layout(new)
            self.modified.set_value(True)

    async def do_set_visible(self, block_name: str, visible: bool) -> None:
        """Show (activate) or hide a child; the manager goes through Disabled."""
        await self.put_layout(self._edited_layout(block_name, visible=visible))

    async def do_set_position(self, block_name: str, x: float, y: float) -> None:
        """Move a child on the canvas."""
        await self.put_layout(self._edited_layout(block_name, x=x, y=y))

    def _edited_layout(self, block_name: str, **changes: Any) -> dict[str, Any]:
        layout_rows = tables.rows(self.layout.value)
        for row in layout_rows:
            if row["name"] == block_name:
                row.update(changes)
                return tables.columns(self.layout.meta, layout_rows)
        known = ", ".join(r["name"] for r in layout_rows) or "none"
        raise BadValueError(f"{self.mri}: no child {block_name!r} (children: {known})")

"""The Editor's calls of a manager: load, save and edits of its tables.

A mixin of :class:`~malcolm.controllers.manager.ManagerController`. Every
call checks what it was given as a whole before anything changes; ``save``
is all or nothing: the Save phase runs first, then the file is written and
``design`` changes, and a failure of either leaves the file and ``design``
as they were.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

from malcolm.core import Attribute, BadValueError, MalcolmError
from malcolm.editor import plan, tables
from malcolm.editor.plan import FIXED_KINDS, plain_value
from malcolm.editor.runtime import (
    EditorPart,
    ExportRuntime,
    FixedRuntime,
    FollowerRuntime,
)
from malcolm.editor.store import WriteSeenThrough
from malcolm.parts.design import Design, ExportPart, PalettePart

if TYPE_CHECKING:
    from malcolm.editor.store import DesignStore
    from malcolm.fsm import Transition


class DesignCalls:
    """``load``/``design`` put, ``save``, and the table and layout edits."""

    if TYPE_CHECKING:  # from the rest of ManagerController
        mri: str
        store: DesignStore | None
        editor_parts: list[EditorPart]
        fixed_records: list[Any]
        model_value: str
        inactive: set[str]
        design: Attribute
        modified: Attribute
        layout: Attribute
        exports: Attribute
        followers: Attribute
        fixed: Attribute
        model_attr: Attribute
        block: Any

        def add_part(self, part: Any) -> None: ...
        def remove_part(self, name: str) -> None: ...
        def _default_layout(self) -> dict[str, Any]: ...
        async def fire(self, trigger: str, before_move: Any = None) -> Transition: ...
        async def settle(self) -> None: ...
        async def operation(self, name: str, coro: Any, interrupt: bool = False): ...
        async def put(self, name: str, value: Any) -> None: ...

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
        self.fixed.set_value(
            [
                {"name": p.target, "value": plan.fixed_text(p.value, p.kind)}
                for p in self._of(FixedRuntime)
            ]
        )

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

    # ---- load
    async def do_load(self, design: str) -> None:
        """Load a design (same as a put of ``design``)."""
        await self.put("design", design)

    def _refresh_choices(self) -> None:
        """``design``'s choices: "" and the saved designs and templates."""
        assert self.store is not None
        choices = ["", *self.store.names()]
        if tuple(choices) != self.design.meta.choices:
            self.design.meta.choices = tuple(choices)
            self.block.notify([[["design", "meta", "choices"], choices]])

    async def put_design(self, name: str) -> None:
        if not name:
            raise BadValueError(f"{self.mri}.design: name a design to load")
        assert self.store is not None
        # read in a worker thread; ConfigError / BadValueError: nothing changed
        design = await self.store.read(name)
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

    # ---- save
    async def do_save(self, design: str = "") -> None:
        """Save the current settings as a design (default: the loaded one)."""
        name = design or self.design.value
        if not name:
            raise BadValueError(f"{self.mri}.save: name the design to save")
        store = self.store
        assert store is not None
        path = store.check_writable(name)  # refused before the manager leaves Ready

        async def commit() -> None:
            # after the Save phase, before the move back: all or nothing
            records = self.design_records()
            fixed = [r for r in records if type(r) in FIXED_KINDS.values()]
            parts = plan.build_parts(
                self,
                plan.records_from_tables(self) + fixed,
            )

            def written() -> None:
                self._install(parts)
                self._refresh_choices()
                self.design.set_value(name)
                self.modified.set_value(False)

            try:
                # in a worker thread, the loop live meanwhile
                await store.write(name, records)
            except WriteSeenThrough as e:
                # interrupted (abort, disable) while the file was written:
                # the file and ``design`` still agree before giving way
                if e.path is not None:
                    written()
                raise
            except OSError as e:
                raise MalcolmError(
                    f"{self.mri}: design {name!r} could not be written to {path}:"
                    f" {e.strerror or e}"
                ) from None
            written()

        async def save() -> None:
            await self.fire("save")
            await self.fire("done", before_move=commit)
            await self.settle()

        await self.operation("save", save())

    # ---- edits of the tables and the layout
    async def _edit_tables(
        self,
        exports: list[dict[str, Any]] | None = None,
        followers: list[dict[str, Any]] | None = None,
        layout: list[dict[str, Any]] | None = None,
        fixed: list[Any] | None = None,
    ) -> None:
        """Change the tables: the manager goes to Disabled with the new parts.

        ``fixed``: the new fixed records (an attribute both fixed and
        exported or followed is then refused); else the current ones, less
        any attribute the edit exports or follows.
        """
        records = plan.records_from_tables(self, exports, followers)
        if fixed is not None:
            records += fixed
        else:
            # an attribute now exported or followed is no longer fixed
            moving = {
                r.source if isinstance(r, ExportPart) else r.name for r in records
            }
            records += [r for r in self.fixed_records if r.name not in moving]
        parts = plan.build_parts(self, records)

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

    async def put_fixed(self, value: dict[str, Any]) -> None:
        """Rows ``name`` (CHILD.ATTRIBUTE), ``value`` (JSON text); written on
        reset, as the manager leaves Disabled."""
        await self._edit_tables(fixed=plan.records_from_fixed(self, tables.rows(value)))

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

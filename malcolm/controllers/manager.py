"""ManagerController: a block that manages children through a design.

The Editor's fields live on the manager's own structure, where pymalcolm
clients look for them: ``design`` (put = load), ``modified``, ``layout``
(the palette), ``exports``, ``followers``, ``fixed`` and ``model``; methods ``save``,
``load``, ``set_visible`` and ``set_position`` (their work is in
:mod:`.designs`). Each export, follower and fixed row becomes a part
(``malcolm.editor.runtime``). A followed or fixed child attribute changed
by anyone but the manager puts it in Fault, naming it (docs/editor.md);
reset writes the design's values back.
"""

from __future__ import annotations

import asyncio
import logging
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
from malcolm.editor import tables
from malcolm.editor.plan import FIXED_KINDS, default_designs_dir, fixed_kind
from malcolm.editor.runtime import EditorPart
from malcolm.editor.store import DesignStore
from malcolm.fsm import Model, Transition
from malcolm.parts.base import ChildPart

from .base import DEFAULT_PHASE_TIMEOUT, Controller
from .designs import DesignCalls

__all__ = [
    "FIXED_KINDS",
    "ManagerController",
    "default_designs_dir",
    "fixed_kind",
]

log = logging.getLogger(__name__)

#: states tagged so are where a manager does not check its Fixed and
#: Follower rows (Disabled, Disabling, Fault, Resetting, Loading)
QUIET = "quiet"


def _s(description: str) -> StringMeta:
    return StringMeta(description, writeable=True)


class ManagerController(DesignCalls, Controller):
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
        #: the followers' writes in progress
        self.background: set[asyncio.Future[Any]] = set()
        super().__init__(mri, parts, description, phase_timeout, phase_timeouts, model)
        self._quiet = self.model.states_tagged(QUIET)
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
        self.fixed = self._add_attr("fixed", tables.fixed_meta())
        self.model_attr = self._add_attr(
            "model", StringMeta("The model this block conforms to (metaOf)")
        )

    def method_meta_save(self) -> MethodMeta:
        return MethodMeta(
            MapMeta({"design": _s("Name to save the design as")}),
            description="Save the current settings as a design",
            defaults={"design": ""},
        )

    def method_meta_load(self) -> MethodMeta:
        return MethodMeta(
            MapMeta({"design": _s("Design to load")}, ["design"]),
            description="Load a design",
        )

    def method_meta_set_visible(self) -> MethodMeta:
        return MethodMeta(
            MapMeta(
                {
                    "block_name": _s("Child name"),
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
                    "block_name": _s("Child name"),
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

    def child_writer(self, mri: str, field: str) -> str | None:
        """Who is writing ``mri.field`` now (see controllers/writers.py)."""
        assert self.process is not None
        return self.process.get_controller(mri).writer_of(field)

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

    async def put(self, name: str, value: Any) -> None:
        if name == "design" and self.store is not None:
            self._refresh_choices()  # a design saved by another hand is loadable
        await super().put(name, value)

    async def stop(self) -> None:
        for part in self.editor_parts:
            part.detach()
        for fut in list(self.background):
            fut.cancel()
        await super().stop()

    # ---- drift: Fault when a followed or fixed child differs
    def is_quiet(self) -> bool:
        """Whether rows are not checked in the current state (tag ``quiet``)."""
        return self._state in self._quiet

    def verify(self, part: EditorPart) -> None:
        """Fault if ``part``'s child attribute is not what its row expects."""
        if part.pending or self.is_quiet() or part not in self.editor_parts:
            return
        message = part.mismatch()
        if message:
            self.report_drift(message)

    def verify_all(self) -> None:
        for part in list(self.editor_parts):
            self.verify(part)

    def report_drift(self, message: str) -> None:
        """A row's child attribute was changed by another hand: Fault.

        Raised (MalcolmError) to the operation that found it while checking
        its own work, so that its caller gets the reason.
        """
        if self.model.is_state(self._state, "fault"):
            return
        op = self._op
        inside = op is not None and op is asyncio.current_task()
        reason = f"{self.mri}: {message}"
        self.fault_now(reason)
        if inside:
            raise MalcolmError(reason)

    def on_moved(self, t: Transition) -> None:
        super().on_moved(t)
        if t.trigger == "done" and not self.is_quiet():
            self.verify_all()

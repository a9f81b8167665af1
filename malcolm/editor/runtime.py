"""The parts a Manager's tables turn into: one per export, follower and fixed row.

- ``ExportRuntime``: a manager field mirroring a child attribute (or
  method), live; writes to it go to the child.
- ``FollowerRuntime``: a child attribute set whenever a manager attribute
  changes.
- ``FixedRuntime``: a child attribute held at a saved value; written on
  reset and load.

A change of a followed or fixed child attribute made by the manager itself
(a put whose origin is the manager: its parts' Tasks, these parts' own
writes) moves what the row expects to the new value, until the source
changes again (a follower) or reset or load writes the design's value back;
a change by anyone else (another client, the hardware) is reported to the
manager, which goes to Fault if the row's attribute is not what it expects
(docs/editor.md).
"""

from __future__ import annotations

import asyncio
import copy
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from malcolm.controllers.writers import writing_as
from malcolm.core import Attribute, BadValueError, Meta, Method, Subscription
from malcolm.fsm import RunnableDevice, Stateful, phases_of
from malcolm.hooks import Task
from malcolm.parts.base import Part, PartRegistrar

if TYPE_CHECKING:
    from malcolm.controllers.manager import ManagerController


_UNSET: Any = object()


def same(a: Any, b: Any) -> bool:
    """Equality that treats lists and tuples alike (table columns, arrays)."""
    if isinstance(a, list | tuple) and isinstance(b, list | tuple):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if isinstance(a, float) and isinstance(b, float) and a != a and b != b:
        return True  # NaN: a child held at NaN is where the design wants it
    return a == b


def writeable_attribute(
    manager: ManagerController, mri: str, field: str, dotted: str, what: str
) -> Attribute:
    """The child attribute a follower or fixed row writes, or BadValueError."""
    target = manager.child_field(mri, field, dotted)
    if not isinstance(target, Attribute) or not target.meta.writeable:
        why = "a method" if isinstance(target, Method) else "read-only"
        raise BadValueError(
            f"{manager.mri}: {what} {dotted} must be a writeable attribute,"
            f" but {mri}.{field} is {why}"
        )
    return target


def compatible(source: Meta, target: Meta) -> bool:
    """Whether values of ``source`` can be written to ``target`` (a follower)."""
    from malcolm.core import NumberMeta, TableMeta

    if isinstance(source, NumberMeta) and isinstance(target, NumberMeta):
        # any number fits a float; only an integer fits an integer
        return target.dtype.startswith("float") or not source.dtype.startswith("float")
    if isinstance(source, TableMeta) and isinstance(target, TableMeta):
        return list(source.elements) == list(target.elements)
    return type(source) is type(target)


def type_of(meta: Meta) -> str:
    """A meta's type in messages: ``float64``, ``StringMeta``..."""
    return getattr(meta, "dtype", None) or type(meta).__name__


class EditorPart(Part):
    """Base of the table parts: knows its manager and the child field it watches."""

    def __init__(self, name: str, manager: ManagerController) -> None:
        super().__init__(name)
        self.manager = manager
        self.subs: list[Subscription] = []
        self.pending = 0  # writes of the manager's own still in flight

    def attach(self) -> None:
        """Subscribe (the process exists and the block is added)."""

    def watch(self, mri: str, field: str, callback: Callable[[Any], None]) -> None:
        """Call ``callback(value)`` now and whenever ``mri.field`` changes."""
        process = self.manager.process
        assert process is not None
        self.subs.append(process.subscribe([mri, field, "value"], callback, False))

    def detach(self) -> None:
        process = self.manager.process
        for sub in self.subs:
            if process is not None:
                process.unsubscribe(sub)
        self.subs.clear()

    def mismatch(self) -> str | None:
        """Why the child differs from what the design says, or None."""
        return None

    async def write(self, mri: str, field: str, value: Any) -> None:
        """A write of the manager's own: drift checks wait until it is done."""
        assert self.manager.process is not None
        self.pending += 1
        try:
            with writing_as(self.manager.mri):
                await self.manager.process.put([mri, field], value)
        finally:
            self.pending -= 1
        self.manager.verify(self)

    def accept(self) -> None:
        """The manager itself changed the child: the row now expects that."""

    def on_child_change(self, _value: Any) -> None:
        mri, field = self.watched
        if self.manager.child_writer(mri, field) == self.manager.mri:
            self.accept()
        elif self.pending == 0:
            self.manager.verify(self)

    @property
    def watched(self) -> tuple[str, str]:
        """The child ``(mri, field)`` this row holds."""
        raise NotImplementedError


class ExportRuntime(EditorPart):
    """Row ``name, source, description`` of the export table."""

    def __init__(
        self, name: str, source: str, description: str, manager: ManagerController
    ) -> None:
        super().__init__(f"export:{name}", manager)
        self.field = name
        self.source = source
        self.description = description
        self.child_mri, self.child_field = manager.resolve(source)

    def child(self) -> Attribute | Method:
        return self.manager.child_field(self.child_mri, self.child_field)

    def setup(self, registrar: PartRegistrar) -> None:
        target = self.child()
        if isinstance(target, Method):
            meta = copy.deepcopy(target.meta)
            if self.description:
                meta.description = self.description
            registrar.add_method(self.call, self.field, meta)
            return
        meta = copy.deepcopy(target.meta)
        if self.description:
            meta.description = self.description
        writeable = target.meta.writeable
        meta.writeable = writeable
        self.attr = registrar.add_attribute(
            self.field, meta, target.value, put=self.put if writeable else None
        )
        if writeable and takes_configure_args(self.manager):
            registrar.add_configure_arg(self.field, copy.deepcopy(meta), None)

    def attach(self) -> None:
        target = self.child()
        if isinstance(target, Attribute):
            self.watch(self.child_mri, self.child_field, self.mirror)

    def mirror(self, value: Any) -> None:
        # subscriptions deliver plain data (a table as lists plus its typeid):
        # back to the canonical value the child attribute holds
        if value is not None:
            value = self.attr.meta.validate(value)
        self.attr.set_value(value, validate=False)

    async def put(self, value: Any) -> None:
        assert self.manager.process is not None
        await self.manager.process.put([self.child_mri, self.child_field], value)

    async def call(self, **params: Any) -> Any:
        assert self.manager.process is not None
        return await self.manager.process.post(
            [self.child_mri, self.child_field], params
        )


def takes_configure_args(manager: ManagerController) -> bool:
    """Whether the manager's ``configure()`` takes its exports as arguments:
    it has the call, and the phases RunnableExportRuntime hooks."""
    hooked = {
        phase
        for klass in RunnableExportRuntime.__mro__
        for fn in vars(klass).values()
        for phase in phases_of(fn)
    }
    return "configure" in manager.model.methods and all(
        manager.resolve_phase(phase) is not None for phase in hooked
    )


class RunnableExportRuntime(ExportRuntime):
    """An export on a runnable manager: a writeable one is a configure argument."""

    @RunnableDevice.Configure
    async def configure(self, task: Task, device: Any) -> None:
        value = device.params.get(self.field)
        if value is not None:
            await task.put((self.child_mri, self.child_field), value)


class FollowerRuntime(EditorPart):
    """Row ``name, source`` of the follower table: child ``name`` follows ``source``."""

    def __init__(
        self,
        name: str,
        source: str,
        manager: ManagerController,
        source_meta: Meta | None = None,
    ) -> None:
        """``source_meta``: the meta of ``source`` if it is not yet a field."""
        super().__init__(f"follower:{name}", manager)
        self.target = name
        self.source = source
        self.child_mri, self.child_field = manager.resolve(name)
        target = writeable_attribute(
            manager, self.child_mri, self.child_field, name, "follower"
        )
        if source_meta is None:
            field = manager.block[source] if source in manager.block else None
            if not isinstance(field, Attribute):
                raise BadValueError(
                    f"{manager.mri}: follower {name} follows {source!r}, which is"
                    " not an attribute of the manager"
                )
            source_meta = field.meta
        if not compatible(source_meta, target.meta):
            raise BadValueError(
                f"{manager.mri}: follower {name} ({type_of(target.meta)})"
                f" cannot follow {source} ({type_of(source_meta)})"
            )

        #: a value the manager itself gave the child, held until the source
        #: changes or apply() (reset, load) follows the source again
        self.held: Any = _UNSET

    @property
    def watched(self) -> tuple[str, str]:
        return self.child_mri, self.child_field

    def source_value(self) -> Any:
        return self.manager.block.attribute(self.source).value

    def expected(self) -> Any:
        """What the child should be: the source, or what the manager set."""
        return self.source_value() if self.held is _UNSET else self.held

    def actual(self) -> Any:
        return self.manager.child_field(self.child_mri, self.child_field).value

    def accept(self) -> None:
        self.held = self.actual()

    def attach(self) -> None:
        self.watch(self.manager.mri, self.source, self.on_source)
        self.watch(self.child_mri, self.child_field, self.on_child_change)

    def on_source(self, value: Any) -> None:
        self.held = _UNSET
        if self.manager.following and not same(value, self.actual()):
            self.pending += 1  # counted now: the child changes before the put ends
            fut = asyncio.ensure_future(self._follow(value))
            self.manager.background.add(fut)
            fut.add_done_callback(self.manager.background.discard)

    async def _follow(self, value: Any) -> None:
        try:
            await self.write(self.child_mri, self.child_field, value)
        except Exception as e:
            self.manager.report_drift(
                f"{self.target} could not follow {self.source}: {e}"
            )
        finally:
            self.pending -= 1
            self.manager.verify(self)

    def mismatch(self) -> str | None:
        expected, actual = self.expected(), self.actual()
        if same(expected, actual):
            return None
        source = self.source_value()
        why = ""
        if not same(expected, source):
            why = f" (set by the manager; {self.source} is {source!r})"
        return (
            f"{self.target} follows {self.source}: expected {expected!r}{why},"
            f" but it is {actual!r}"
        )

    async def apply(self) -> None:
        """Follow the source again: write its value to the child."""
        self.held = _UNSET
        if not same(self.expected(), self.actual()):
            await self.write(self.child_mri, self.child_field, self.expected())

    @Stateful.Reset
    async def reset(self, task: Task, device: Any) -> None:
        await self.apply()


class FixedRuntime(EditorPart):
    """A ``fixed.<Type>`` record: child attribute ``name`` held at ``value``."""

    def __init__(
        self, name: str, value: Any, kind: str, manager: ManagerController
    ) -> None:
        super().__init__(f"fixed:{name}", manager)
        self.target = name
        self.kind = kind
        self.child_mri, self.child_field = manager.resolve(name)
        target = writeable_attribute(
            manager, self.child_mri, self.child_field, name, "fixed"
        )
        try:
            #: the design's value
            self.value = target.validate(value)
        except (BadValueError, TypeError, ValueError) as e:
            raise BadValueError(
                f"{manager.mri}: fixed {name}: {target.meta.__class__.__name__}"
                f" refuses {value!r}: {e}"
            ) from None
        #: what the row expects now: the design's value, or what the manager
        #: itself gave the child since
        self.expected = self.value

    @property
    def watched(self) -> tuple[str, str]:
        return self.child_mri, self.child_field

    def actual(self) -> Any:
        return self.manager.child_field(self.child_mri, self.child_field).value

    def accept(self) -> None:
        self.expected = self.actual()

    def attach(self) -> None:
        self.watch(self.child_mri, self.child_field, self.on_child_change)

    def mismatch(self) -> str | None:
        actual = self.actual()
        if same(self.expected, actual):
            return None
        why = ""
        if not same(self.expected, self.value):
            why = f" (set by the manager; the design has {self.value!r})"
        return f"{self.target} is fixed at {self.expected!r}{why}, but it is {actual!r}"

    async def apply(self) -> None:
        """Write the design's value back (reset and load use it)."""
        self.expected = self.value
        if not same(self.value, self.actual()):
            await self.write(self.child_mri, self.child_field, self.value)

    @Stateful.Reset
    async def reset(self, task: Task, device: Any) -> None:
        await self.apply()

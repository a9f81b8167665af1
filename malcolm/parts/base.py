"""Part: a piece of a block that adds fields and hooks into phases."""

from __future__ import annotations

import inspect
import threading
import weakref
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from malcolm.core import Alarm, Attribute, MapMeta, Meta, Method, MethodMeta
from malcolm.fsm import phases_of
from malcolm.hooks import BlockView

from .signature import method_meta_from

if TYPE_CHECKING:
    from malcolm.controllers.base import Controller


_PHASE_FUNCTIONS: weakref.WeakKeyDictionary[type, tuple[tuple[str, str, Any], ...]] = (
    weakref.WeakKeyDictionary()
)
_LOCK = threading.Lock()


def phase_functions(cls: type) -> tuple[tuple[str, str, Any], ...]:
    """``(phase, attribute name, class attribute)`` for every phase-decorated
    attribute of ``cls`` (the first definition of a name in the MRO wins), in
    MRO then definition order. Read once per class: the phases of a class's
    functions are fixed once a part of it has been made."""
    with _LOCK:
        found = _PHASE_FUNCTIONS.get(cls)
    if found is not None:
        return found
    out = []
    seen = set()
    for klass in cls.__mro__:
        for attr_name, value in vars(klass).items():
            if attr_name in seen:
                continue
            seen.add(attr_name)
            for phase in phases_of(value):
                out.append((phase, attr_name, value))
    found = tuple(out)
    with _LOCK:
        _PHASE_FUNCTIONS[cls] = found
    return found


class PartRegistrar:
    """What a part's ``setup`` uses to add fields to its controller's block."""

    def __init__(self, controller: Controller, part: Part) -> None:
        self.controller = controller
        self.part = part
        #: names of the block fields this part added (removed with the part)
        self.fields: list[str] = []
        #: configure arguments this part added
        self.configure_args: list[str] = []

    @property
    def mri(self) -> str:
        return self.controller.mri

    def add_attribute(
        self,
        name: str,
        meta: Meta,
        value: Any = None,
        put: Callable[[Any], Any] | None = None,
        alarm: Alarm = Alarm.ok,
    ) -> Attribute:
        """Add an attribute; ``put`` (if given) handles external puts."""
        if put is not None:
            meta.writeable = True
        attr = Attribute(name, meta, value, alarm=alarm, put_handler=put)
        self.controller.block.add(attr)
        self.fields.append(name)
        return attr

    def add_method(
        self,
        func: Callable[..., Any],
        name: str | None = None,
        meta: MethodMeta | None = None,
        returns: MapMeta | None = None,
    ) -> Method:
        """Add a method; its takes are read from the function's signature."""
        name = name or func.__name__
        meta = meta or method_meta_from(func, returns)
        method = Method(name, meta, func)
        self.controller.block.add(method)
        self.fields.append(name)
        return method

    def report_health(self, message: str | None) -> None:
        """Report a problem of this part (a lost connection...), or None once
        it is over: the block's ``health`` shows it as ``part: message``
        (see ``Controller.set_part_health``). The state does not change."""
        self.controller.set_part_health(self.part.name, message)

    def add_configure_arg(
        self, name: str, meta: Meta, default: Any = None, required: bool = False
    ) -> None:
        """Add an argument to configure() and validate() (runnable blocks)."""
        self.controller.add_configure_arg(name, meta, default, required)
        self.configure_args.append(name)


class Part:
    """A named piece of a block.

    Subclasses add fields in ``setup`` and mark methods with phase decorators
    (``@RunnableDevice.Configure``) to run in those phases.
    """

    def __init__(self, name: str) -> None:
        self.name = name

    def setup(self, registrar: PartRegistrar) -> None:
        """Add attributes, methods and configure arguments."""

    def hook_functions(self) -> list[tuple[str, Callable[..., Any]]]:
        """``(phase, bound function)`` for every phase-decorated method."""
        return [
            (phase, getattr(self, name))
            for phase, name, _ in phase_functions(type(self))
        ]

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name}>"


class Controls:
    """Class decorator naming the kind of block a ChildPart controls."""

    def __init__(self, block_type: Any) -> None:
        self.block_type = block_type

    def __call__(self, cls: type) -> type:
        cls.controls = self.block_type  # type: ignore[attr-defined]
        return cls


class ChildPart(Part):
    """A part that controls a child block, reachable as ``self.child``."""

    controls: Any = None

    def __init__(self, name: str, mri: str) -> None:
        super().__init__(name)
        self.mri = mri
        self._controller: Controller | None = None

    def setup(self, registrar: PartRegistrar) -> None:
        self._controller = registrar.controller

    @property
    def child(self) -> BlockView:
        """The child block; writes through it are made on behalf of this
        part's block (docs/editor.md, who may change a fixed attribute)."""
        controller = self._controller
        assert controller is not None and controller.process is not None
        return BlockView(controller.process, self.mri, controller.mri)


ChildControllerPart = ChildPart


def input_mri(input: str | None, mri: str | None) -> str:
    """The mri a part's ``input`` (the design document's name) or ``mri``
    gives; both may be given only if they agree."""
    if input is not None and mri is not None and input != mri:
        raise ValueError(f"input {input!r} and mri {mri!r} name different blocks")
    target = input if input is not None else mri
    if not target:
        raise ValueError("needs an 'input' (the mri of the block it controls)")
    return target


def is_async(func: Callable[..., Any]) -> bool:
    return inspect.iscoroutinefunction(func)

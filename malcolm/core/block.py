"""Block: an mri, a meta, and an ordered set of attributes and methods."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

from .errors import NotFoundError
from .fields import Attribute, Change, Field, Method
from .metas import BlockMeta
from .threads import LoopOwner

BLOCK_TYPEID = "malcolm:core/Block:1.0"


class Block:
    """The data of one block. Its controller owns it; the process publishes it.

    Fields are reached as ``block["counter"]`` or ``block.counter``.
    """

    def __init__(self, mri: str, description: str = "", tags: tuple[str, ...] = ()):
        self.mri = mri
        self.meta = BlockMeta(description=description, tags=tags)
        self._fields: dict[str, Field] = {}
        self._listener: Callable[[str, list[Change]], None] | None = None
        #: the loop that owns this block's state (set by its process at start)
        self.owner: LoopOwner | None = None

    # ---- structure
    def add(self, fld: Field) -> Field:
        """Add a field (or replace one with the same name)."""
        if self._off_loop(f"{self.mri}.{fld.name}", self.add, fld):
            return fld
        if fld.name in ("meta", "typeid") or not fld.name.isidentifier():
            raise ValueError(f"{self.mri}: invalid field name {fld.name!r}")
        old = self._fields.get(fld.name)
        existed = old is not None
        if old is not None and old is not fld:
            old.block = None
        fld.block = self
        self._fields[fld.name] = fld
        if not existed:
            self.meta.fields.append(fld.name)
        self.notify(self._structure_changes(fld.name))
        return fld

    def remove(self, name: str) -> None:
        """Remove a field (nothing happens if there is none)."""
        if self._off_loop(f"{self.mri}.{name}", self.remove, name):
            return
        if name in self._fields:
            self._fields.pop(name).block = None
            self.meta.fields.remove(name)
            self.notify([[[name]], [["meta", "fields"], list(self.meta.fields)]])

    def _off_loop(self, what: str, func: Callable[..., Any], *args: Any) -> bool:
        owner = self.owner
        if owner is None or owner.here():
            return False
        return owner.elsewhere(what, func, *args)[0]

    def _structure_changes(self, name: str) -> list[Change]:
        return [
            [[name], self._fields[name].to_dict()],
            [["meta", "fields"], list(self.meta.fields)],
        ]

    def __contains__(self, name: object) -> bool:
        return name in self._fields

    def __iter__(self) -> Iterator[str]:
        return iter(self._fields)

    def __getitem__(self, name: str) -> Field:
        try:
            return self._fields[name]
        except KeyError:
            raise NotFoundError(
                f"{self.mri} has no field {name!r}"
                f" (fields: {', '.join(self._fields) or 'none'})"
            ) from None

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_"):
            raise AttributeError(name)
        try:
            return self._fields[name]
        except KeyError:
            raise AttributeError(f"{self.mri} has no field {name!r}") from None

    def attribute(self, name: str) -> Attribute:
        fld = self._fields.get(name)
        if type(fld) is Attribute:  # the common case, without __getitem__
            return fld
        fld = self[name]
        if not isinstance(fld, Attribute):
            raise NotFoundError(f"{self.mri}.{name} is not an attribute")
        return fld

    def method(self, name: str) -> Method:
        fld = self._fields.get(name)
        if type(fld) is Method:  # the common case, without __getitem__
            return fld
        fld = self[name]
        if not isinstance(fld, Method):
            raise NotFoundError(f"{self.mri}.{name} is not a method")
        return fld

    @property
    def attributes(self) -> dict[str, Attribute]:
        return {k: f for k, f in self._fields.items() if isinstance(f, Attribute)}

    @property
    def methods(self) -> dict[str, Method]:
        return {k: f for k, f in self._fields.items() if isinstance(f, Method)}

    # ---- changes
    def set_listener(self, listener: Callable[[str, list[Change]], None] | None):
        self._listener = listener

    def notify(self, changes: list[Change]) -> None:
        if self._listener is not None:
            self._listener(self.mri, changes)

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {"typeid": BLOCK_TYPEID, "meta": self.meta.to_dict()}
        for name, fld in self._fields.items():
            d[name] = fld.to_dict()
        return d

    def __repr__(self) -> str:
        return f"<Block {self.mri}>"

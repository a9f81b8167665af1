"""Soft stand-ins for Channel Access attributes, and gui groups.

A ``ca.Double`` (``ca.LongString``, ``ca.Enum``...) section of a definition
makes one attribute bound to a PV. Until the Channel Access adapter exists,
the attribute is bound to a :class:`SoftChannel` instead: an in-memory
channel that keeps the PV names (``pv``, the readback ``rbv``) as metadata
and whose readback follows the demand as soon as it is put. Nothing talks
to an IOC.

- ``writeable: true`` lets the attribute be put (the put goes to the
  channel, then the attribute takes the channel's readback);
- ``widget: textinput`` adds the tag ``widget:textinput`` (without one, a
  writeable attribute gets the kind's usual input widget and a read-only
  one ``widget:textupdate``);
- ``group: configuration`` adds the tag ``group:configuration``;
- ``rbv`` names the readback PV; ``rbv_suffix`` makes it ``pv + suffix``;
  by default the readback is ``pv`` itself. One of ``pv``/``rbv`` is needed.
- numbers take ``low``/``high`` (limits), ``units`` and ``precision``;
- ``ca.Enum`` takes ``choices`` (a list of labels). Without them it has
  ``["0", "1"]``, the two states of a bo/bi record with no labels set: the
  soft channel cannot ask an IOC for the record's labels, which the Channel
  Access adapter will read instead.
- ``ca.Table`` takes ``columns``: column name -> type (``Long``/``Int``,
  ``Double``/``Float``, ``String``, ``Bool``), in order; its value is a table
  (one array per column), empty at first.

``gui.Group`` sections make a :class:`GroupPart`: an attribute named after
the group, a ChoiceMeta of ``expanded``/``collapsed`` tagged
``widget:group``, that attributes join with ``group:<name>``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

from malcolm.core import (
    Attribute,
    BooleanArrayMeta,
    BooleanMeta,
    ChoiceMeta,
    Meta,
    NumberArrayMeta,
    NumberMeta,
    StringArrayMeta,
    StringMeta,
    TableMeta,
)
from malcolm.core.metas import ArrayMeta

from .base import Part, PartRegistrar

__all__ = [
    "CABoolPart",
    "CADoublePart",
    "CAEnumPart",
    "CALongPart",
    "CALongStringPart",
    "CAPart",
    "CAStringPart",
    "CATablePart",
    "GroupPart",
    "SoftChannel",
]


class SoftChannel:
    """An in-memory PV pair: a put sets the demand and, at once, the readback."""

    def __init__(self, pv: str | None, rbv: str | None, value: Any = None) -> None:
        self.pv = pv
        self.rbv = rbv
        self.value = value
        self.puts = 0

    def put(self, value: Any) -> Any:
        """Write ``value`` to the demand PV; returns the readback."""
        if self.pv is None:
            raise ValueError(f"{self.rbv} is a readback: it has no PV to put to")
        self.value = value
        self.puts += 1
        return self.value

    def get(self) -> Any:
        """The readback value."""
        return self.value

    def __repr__(self) -> str:
        return f"SoftChannel(pv={self.pv!r}, rbv={self.rbv!r})"


class CAPart(Part):
    """One attribute bound to a (soft) channel; subclasses choose the meta."""

    #: widget used when the section names none and the attribute is writeable
    input_widget: ClassVar[str] = "textinput"

    def __init__(
        self,
        name: str,
        pv: str | None = None,
        rbv: str | None = None,
        rbv_suffix: str | None = None,
        description: str = "",
        widget: str | None = None,
        group: str | None = None,
        writeable: bool = False,
        label: str = "",
    ) -> None:
        super().__init__(name)
        if not name.isidentifier():
            raise ValueError(f"attribute name {name!r} is not an identifier")
        if pv is None and rbv is None:
            raise ValueError("needs a 'pv' or an 'rbv'")
        if rbv is None:
            rbv = pv if rbv_suffix is None else f"{pv}{rbv_suffix}"
        elif rbv_suffix is not None:
            raise ValueError("give 'rbv' or 'rbv_suffix', not both")
        if writeable and pv is None:
            raise ValueError("a writeable attribute needs a 'pv' to put to")
        self.pv = pv
        self.rbv = rbv
        self.description = description
        self.widget = widget or (self.input_widget if writeable else "textupdate")
        self.group = group
        self.writeable = bool(writeable)
        self.label = label
        self.meta = self.make_meta(description, self.tags(), self.writeable, label)
        self.channel = SoftChannel(pv, rbv, self.meta.default())
        self.attr: Attribute | None = None

    def tags(self) -> list[str]:
        tags = [f"widget:{self.widget}"]
        if self.group:
            tags.append(f"group:{self.group}")
        return tags

    def make_meta(
        self, description: str, tags: Sequence[str], writeable: bool, label: str
    ) -> Meta:
        raise NotImplementedError

    def setup(self, registrar: PartRegistrar) -> None:
        self.attr = registrar.add_attribute(
            self.name,
            self.meta,
            self.channel.get(),
            put=self.put if self.writeable else None,
        )

    def put(self, value: Any) -> None:
        assert self.attr is not None
        self.attr.set_value(self.channel.put(value))


class _NumberPart(CAPart):
    dtype: ClassVar[str] = "float64"

    def __init__(
        self,
        name: str,
        pv: str | None = None,
        rbv: str | None = None,
        rbv_suffix: str | None = None,
        description: str = "",
        widget: str | None = None,
        group: str | None = None,
        writeable: bool = False,
        label: str = "",
        low: float | None = None,
        high: float | None = None,
        units: str = "",
        precision: int | None = None,
    ) -> None:
        display: dict[str, Any] = {}
        if low is not None:
            display["limitLow"] = low
        if high is not None:
            display["limitHigh"] = high
        if units:
            display["units"] = units
        if precision is not None:
            display["precision"] = precision
        self.display = display
        super().__init__(
            name, pv, rbv, rbv_suffix, description, widget, group, writeable, label
        )

    def make_meta(
        self, description: str, tags: Sequence[str], writeable: bool, label: str
    ) -> Meta:
        return NumberMeta(
            self.dtype, description, tags, writeable, label, display=self.display
        )


class CADoublePart(_NumberPart):
    """``ca.Double``: a float64 attribute."""


class CALongPart(_NumberPart):
    """``ca.Long`` (and ``ca.Int``): an int32 attribute."""

    dtype = "int32"


class CAStringPart(CAPart):
    """``ca.String``: a string attribute (a stringin/stringout record)."""

    def make_meta(
        self, description: str, tags: Sequence[str], writeable: bool, label: str
    ) -> Meta:
        return StringMeta(description, tags, writeable, label)


class CALongStringPart(CAStringPart):
    """``ca.LongString``: a string held in a char waveform; edited as text."""

    input_widget = "textarea"


class CABoolPart(CAPart):
    """``ca.Bool``: a boolean attribute (a bo/bi record read as 0/1)."""

    input_widget = "checkbox"

    def make_meta(
        self, description: str, tags: Sequence[str], writeable: bool, label: str
    ) -> Meta:
        return BooleanMeta(description, tags, writeable, label)


class CAEnumPart(CAPart):
    """``ca.Enum``: one of ``choices`` (default ``["0", "1"]``)."""

    input_widget = "combo"

    def __init__(
        self,
        name: str,
        pv: str | None = None,
        rbv: str | None = None,
        rbv_suffix: str | None = None,
        description: str = "",
        widget: str | None = None,
        group: str | None = None,
        writeable: bool = False,
        label: str = "",
        choices: Sequence[str] | None = None,
    ) -> None:
        if choices is None:
            choices = ["0", "1"]
        if not isinstance(choices, list | tuple) or not all(
            isinstance(c, str) for c in choices
        ):
            raise ValueError(f"choices must be a list of text, not {choices!r}")
        if len(set(choices)) != len(choices) or not choices:
            raise ValueError(f"choices must be different and not empty: {choices}")
        self.choices = list(choices)
        super().__init__(
            name, pv, rbv, rbv_suffix, description, widget, group, writeable, label
        )

    def make_meta(
        self, description: str, tags: Sequence[str], writeable: bool, label: str
    ) -> Meta:
        return ChoiceMeta(self.choices, description, tags, writeable, label)


#: ``ca.Table`` column types -> the column's array meta
TABLE_COLUMN_TYPES: dict[str, Any] = {
    "Long": lambda: NumberArrayMeta("int32"),
    "Int": lambda: NumberArrayMeta("int32"),
    "Double": lambda: NumberArrayMeta("float64"),
    "Float": lambda: NumberArrayMeta("float64"),
    "String": StringArrayMeta,
    "Bool": BooleanArrayMeta,
}


class CATablePart(CAPart):
    """``ca.Table``: a table whose ``columns`` map each name to its type."""

    input_widget = "table"

    def __init__(
        self,
        name: str,
        pv: str | None = None,
        rbv: str | None = None,
        rbv_suffix: str | None = None,
        description: str = "",
        widget: str | None = None,
        group: str | None = None,
        writeable: bool = False,
        label: str = "",
        columns: dict[str, str] | None = None,
    ) -> None:
        if not isinstance(columns, dict) or not columns:
            raise ValueError(
                f"columns must map each column name to its type, not {columns!r}"
            )
        elements: dict[str, ArrayMeta] = {}
        for column, kind in columns.items():
            if not str(column).isidentifier():
                raise ValueError(f"column name {column!r} is not an identifier")
            if not isinstance(kind, str) or kind not in TABLE_COLUMN_TYPES:
                raise ValueError(
                    f"column {column}: type {kind!r} is not one of "
                    + ", ".join(TABLE_COLUMN_TYPES)
                )
            elements[str(column)] = TABLE_COLUMN_TYPES[kind]()
        self.elements = elements
        super().__init__(
            name, pv, rbv, rbv_suffix, description, widget, group, writeable, label
        )

    def make_meta(
        self, description: str, tags: Sequence[str], writeable: bool, label: str
    ) -> Meta:
        return TableMeta(self.elements, description, tags, writeable, label)


class GroupPart(Part):
    """``gui.Group``: an ``expanded``/``collapsed`` attribute named after it."""

    CHOICES = ("expanded", "collapsed")

    def __init__(self, name: str, label: str = "", description: str = "") -> None:
        super().__init__(name)
        if not name.isidentifier():
            raise ValueError(f"group name {name!r} is not an identifier")
        self.label = label
        self.description = description
        self.attr: Attribute | None = None

    def setup(self, registrar: PartRegistrar) -> None:
        meta = ChoiceMeta(
            self.CHOICES,
            self.description,
            ("widget:group",),
            writeable=True,
            label=self.label or self.name,
        )
        self.attr = registrar.add_attribute(self.name, meta, "expanded")

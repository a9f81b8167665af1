"""Channel Access attributes (``ca.*`` sections), and gui groups.

A ``ca.Double`` (``ca.LongString``, ``ca.Enum``...) section of a definition
makes one attribute bound to a PV pair: read from the readback ``rbv``,
written (if writeable) to ``pv``. The channel comes from the ``ca`` backend
the process chose (:mod:`malcolm.io.backends`; pyepics by default,
:mod:`malcolm.io.ca`, or ``soft``, in memory): see :class:`~malcolm.parts.channel.
ChannelPart` for connecting, alarms, health and puts, and docs/channels.md.

- ``writeable: true`` lets the attribute be put (a put with completion to
  ``pv``, then the attribute takes what a get of the readback says);
- ``widget: textinput`` adds the tag ``widget:textinput`` (without one, a
  writeable attribute gets the kind's usual input widget and a read-only
  one ``widget:textupdate``);
- ``group: configuration`` adds the tag ``group:configuration``;
- ``rbv`` names the readback PV; ``rbv_suffix`` makes it ``pv + suffix``;
  by default the readback is ``pv`` itself. One of ``pv``/``rbv`` is needed.
- numbers take ``low``/``high`` (limits), ``units`` and ``precision``; what
  the definition leaves out is taken from the channel when it reports it;
- ``ca.Enum`` takes ``choices`` (a list of labels). Without them it has
  ``["0", "1"]``, the two states of a bo/bi record with no labels set, until
  the channel reports the record's labels (a soft record reports none
  unless defined with them);
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
from malcolm.io import ChannelInfo, SoftChannel

from .base import Part, PartRegistrar
from .channel import ChannelPart

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
    "SoftChannel",  # malcolm.io.soft's, once defined here
]


class CAPart(ChannelPart):
    """One attribute bound to a ``ca`` channel; subclasses choose the meta."""

    transport = "ca"
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
        assert rbv is not None
        super().__init__(name, rbv, pv if writeable else None, writeable)
        self.pv = pv
        self.rbv = rbv
        self.description = description
        self.widget = widget or (self.input_widget if writeable else "textupdate")
        self.group = group
        self.label = label
        self.meta = self.make_meta(description, self.tags(), self.writeable, label)

    def tags(self) -> list[str]:
        tags = [f"widget:{self.widget}"]
        if self.group:
            tags.append(f"group:{self.group}")
        return tags

    def make_meta(
        self, description: str, tags: Sequence[str], writeable: bool, label: str
    ) -> Meta:
        raise NotImplementedError

    def attribute_meta(self) -> Meta:
        return self.meta


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

    def display_from_info(self, info: ChannelInfo) -> dict[str, Any]:
        """The limits, units and precision ``info`` reports that the
        definition's ``display`` does not already give."""
        found: dict[str, Any] = {}
        if info.limits is not None and not {"limitLow", "limitHigh"} & set(
            self.display
        ):
            found["limitLow"], found["limitHigh"] = info.limits
        if info.units is not None and "units" not in self.display:
            found["units"] = info.units
        if info.precision is not None and "precision" not in self.display:
            found["precision"] = info.precision
        return found

    def meta_from_info(self, meta: Meta, info: ChannelInfo) -> Meta | None:
        """Limits, units and precision the channel reports, where the
        definition gave none."""
        assert isinstance(meta, NumberMeta)
        found = self.display_from_info(info)
        if not found:
            return None
        display = {**meta.display, **found}
        return NumberMeta(
            meta.dtype,
            meta.description,
            meta.tags,
            meta.writeable,
            meta.label,
            display=display,
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
        #: whether the definition named the choices (else the channel may)
        self.choices_given = choices is not None
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

    def meta_from_info(self, meta: Meta, info: ChannelInfo) -> Meta | None:
        """The channel's enum strings, where the definition gave no choices."""
        if self.choices_given or not info.choices:
            return None
        if tuple(info.choices) == tuple(getattr(meta, "choices", ())):
            return None
        return ChoiceMeta(
            info.choices, meta.description, meta.tags, meta.writeable, meta.label
        )


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

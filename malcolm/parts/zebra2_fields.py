"""Zebra2BlockPart: the fields of one box block instance as attributes.

One part per child block (``PCOMP1``, ``SEQ``...), made by the Zebra2
manager (:mod:`malcolm.parts.zebra2_manager`) from the box's layout. Each
field becomes what its type says (docs/zebra2.md has the table):

- param/read/write ``uint`` -> ``uint32``, ``int`` -> ``int32``, ``time``
  -> ``float64`` in the field's units (attribute ``F_UNITS``, a choice),
  ``bit`` -> boolean, ``enum`` -> choice, ``lut`` -> string;
- ``bit_out`` -> boolean, ``pos_out`` -> ``int32`` with ``F_SCALE``,
  ``F_OFFSET``, ``F_UNITS``, ``F_SCALED`` and ``F_CAPTURE``;
- ``bit_mux`` / ``pos_mux`` -> a choice of the outputs it can wire to
  (``F_DELAY`` for a bit_mux); ``ext_out`` -> ``F_CAPTURE`` only;
- ``table`` -> a table of the columns ``B1.F.FIELDS?`` lists;
- ``write`` fields (not readable) -> methods: ``F()`` for an action,
  ``F(value)`` otherwise.

A put is one write to the box (pipelined with a read-back, whose value the
attribute then shows). The box's values reach the attributes from the
manager's ``*CHANGES?`` polls; a value the box cannot read gets an INVALID
alarm. The box judges every value: metas do not refuse what the box might
take (no limits; an enum label the box does not know is sent, and its
``ERR`` comes back naming block and field; nothing changes).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

from malcolm.core import (
    Alarm,
    Attribute,
    BadValueError,
    BooleanMeta,
    ChoiceArrayMeta,
    ChoiceMeta,
    MapMeta,
    Meta,
    MethodMeta,
    NumberArrayMeta,
    NumberMeta,
    StringMeta,
    TableMeta,
)
from malcolm.io.zebra2 import (
    BlockLayout,
    Box,
    Change,
    FieldLayout,
    Zebra2Error,
    pack_table,
    unpack_table,
)

from .base import Part, PartRegistrar

__all__ = ["BoxChoiceMeta", "BoxTableMeta", "RawWords", "Zebra2BlockPart"]


class BoxChoiceMeta(ChoiceMeta):
    """A choice whose puts the box judges: a label it does not list is passed
    on as text (the box's ``ERR Invalid enumeration value`` comes back)."""

    def validate(self, value: Any) -> str:
        if isinstance(value, str) and value not in self.choices and self.choices:
            return value
        return super().validate(value)


class RawWords(list):
    """A table put as the box's 32-bit words (sent as they are)."""


class BoxTableMeta(TableMeta):
    """A table of a box's columns; a put of a flat list of integers is the
    box's words (the box checks the row width)."""

    def validate(self, value: Any) -> Any:
        if isinstance(value, list | tuple) and value:
            if all(isinstance(v, int) and not isinstance(v, bool) for v in value):
                return RawWords(value)
        return super().validate(value)


def _number(dtype: str, description: str, writeable: bool, units: str = "") -> Meta:
    display = {"units": units} if units else None
    return NumberMeta(dtype, description, writeable=writeable, display=display)


def _from_text(meta: Meta, text: str) -> Any:
    """A box value (text) as the meta's value."""
    if isinstance(meta, BooleanMeta):
        return text.strip() not in ("0", "")
    if isinstance(meta, NumberMeta):
        try:
            return meta.validate(text)
        except BadValueError:
            return float(text) if meta.dtype.startswith("float") else int(text, 0)
    return text


def _to_text(meta: Meta, value: Any) -> str:
    """An attribute value as the text the box parses."""
    if isinstance(meta, BooleanMeta):
        return "1" if value else "0"
    if isinstance(value, float):
        return repr(value) if not value.is_integer() else str(int(value))
    return str(value)


class _Binding:
    """An attribute and the box target it mirrors."""

    def __init__(self, attr: Attribute, target: str, field: FieldLayout) -> None:
        self.attr = attr
        self.target = target
        self.field = field
        self.error = False  # the box cannot read it

    @property
    def is_table(self) -> bool:
        return isinstance(self.attr.meta, BoxTableMeta)


class Zebra2BlockPart(Part):
    """Every field of box block ``instance`` (e.g. ``PCOMP1``), bound to
    ``box`` (see the module docstring)."""

    def __init__(self, name: str, box: Box, block: BlockLayout, instance: str) -> None:
        super().__init__(name)
        self.box = box
        self.block = block
        self.instance = instance
        self.bindings: dict[str, _Binding] = {}
        self._registrar: PartRegistrar | None = None

    # ---- building
    def setup(self, registrar: PartRegistrar) -> None:
        self._registrar = registrar
        for f in self.block.fields:
            self._add_field(registrar, f)
        if self.instance == "PCAP":
            self._add_pcap_methods(registrar)
        self.box.watch_state(self._on_state)

    def _add_pcap_methods(self, registrar: PartRegistrar) -> None:
        """``ARM()`` and ``DISARM()``: the box's ``*PCAP.ARM=`` and
        ``*PCAP.DISARM=`` (the design document's ``PCAP.ARM``)."""

        async def arm() -> None:
            await self._send("*PCAP.ARM=", "*PCAP.ARM")

        async def disarm() -> None:
            await self._send("*PCAP.DISARM=", "*PCAP.DISARM")

        for name, func in (("ARM", arm), ("DISARM", disarm)):
            if name not in registrar.controller.block:
                doc = f"Send *PCAP.{name}= to the box"
                registrar.add_method(func, name, MethodMeta(description=doc))

    def _add(
        self, registrar: PartRegistrar, name: str, meta: Meta, f: FieldLayout, attr=None
    ) -> None:
        if name in registrar.controller.block:
            return  # a name a block field already has (cannot happen in tier 2)
        target = f"{self.instance}.{f.name}" + (f".{attr}" if attr else "")
        binding: _Binding
        put = self._putter(name) if meta.writeable else None
        a = registrar.add_attribute(name, meta, meta.default(), put=put)
        binding = _Binding(a, target, f)
        self.bindings[name] = binding
        self.box.watch(self.instance, f.name, attr, self._watcher(binding))

    def _add_field(self, registrar: PartRegistrar, f: FieldLayout) -> None:
        desc = f.description or f.name
        kind, writeable = f.kind, f.type == "param"
        meta: Meta | None = None
        if f.type == "write":
            self._add_method(registrar, f)
            return
        if f.type == "table":
            self._add(registrar, f.name, self._table_meta(f), f)
            return
        if f.type in ("bit_mux", "pos_mux"):
            meta = BoxChoiceMeta(f.labels, desc, writeable=True)
        elif f.type == "bit_out":
            meta = BooleanMeta(desc)
        elif f.type == "pos_out":
            meta = _number("int32", desc, False)
        elif kind == "time":
            meta = _number("float64", desc, f.type in ("param", "time"))
            writeable = f.type in ("param", "time")
        elif kind == "uint":
            maximum = f.fixed.get("MAX", "")
            meta = _number(
                "uint32", f"{desc} (max {maximum})" if maximum else desc, writeable
            )
        elif kind == "int":
            meta = _number("int32", desc, writeable)
        elif kind == "bit":
            meta = BooleanMeta(desc, writeable=writeable)
        elif kind == "enum":
            meta = BoxChoiceMeta(f.labels, desc, writeable=writeable)
        elif kind in ("lut", "scalar"):
            meta = (
                StringMeta(desc, writeable=writeable)
                if kind == "lut"
                else _number("float64", desc, writeable)
            )
        if meta is not None:
            self._add(registrar, f.name, meta, f)
        self._add_attributes(registrar, f)

    def _add_attributes(self, registrar: PartRegistrar, f: FieldLayout) -> None:
        for a in f.attributes:
            name = f"{f.name}_{a}"
            meta: Meta | None = None
            labels = f.attribute_labels.get(a, ())
            if a == "CAPTURE":
                meta = BoxChoiceMeta(labels, f"{f.name}: capture", writeable=True)
            elif a == "UNITS":
                if labels:
                    meta = BoxChoiceMeta(labels, f"{f.name}: units", writeable=True)
                else:
                    meta = StringMeta(f"{f.name}: units", writeable=True)
            elif a in ("SCALE", "OFFSET") and f.type == "pos_out":
                meta = _number("float64", f"{f.name}: {a.lower()}", True)
            elif a == "SCALED":
                meta = _number("float64", f"{f.name}: scaled value", False)
            elif a == "DELAY":
                maximum = f.fixed.get("MAX_DELAY", "")
                meta = _number("uint32", f"{f.name}: clock delay (max {maximum})", True)
            if meta is not None:
                self._add(registrar, name, meta, f, a)

    def _table_meta(self, f: FieldLayout) -> BoxTableMeta:
        elements: dict[str, Any] = {}
        for c in f.columns:
            desc = c.description or c.name
            if c.subtype == "enum":
                elements[c.name] = ChoiceArrayMeta(c.labels, desc, writeable=True)
            elif c.subtype == "int":
                elements[c.name] = NumberArrayMeta("int32", desc, writeable=True)
            else:
                elements[c.name] = NumberArrayMeta("uint32", desc, writeable=True)
        return BoxTableMeta(elements, f.description or f.name, writeable=True)

    def _add_method(self, registrar: PartRegistrar, f: FieldLayout) -> None:
        target = f"{self.instance}.{f.name}"
        if f.subtype == "action":

            async def action() -> None:
                await self._send(f"{target}=", target)

            meta = MethodMeta(description=f.description or f.name)
            registrar.add_method(action, f.name, meta)
            return

        async def write(value: str) -> None:
            await self._send(f"{target}={value}", target)

        takes = MapMeta({"value": StringMeta("Value", writeable=True)}, ["value"])
        registrar.add_method(write, f.name, MethodMeta(takes, description=f.name))

    # ---- the box -> attributes
    def _watcher(self, binding: _Binding) -> Callable[[Change], None]:
        def on_change(change: Change) -> None:
            attr = binding.attr
            if change.kind == "error":
                binding.error = True
                attr.set_alarm(
                    Alarm.invalid(f"{binding.target}: the box cannot read it")
                )
                return
            try:
                if binding.is_table:
                    value = self._table_value(binding, change.value.split())
                else:
                    value = _from_text(attr.meta, change.value)
                value = attr.validate(value)
            except (BadValueError, ValueError) as e:
                attr.set_alarm(Alarm.invalid(f"{binding.target}={change.value!r}: {e}"))
                return
            binding.error = False
            attr.set_value(value, alarm=Alarm.ok, validate=False)

        return on_change

    def _table_value(self, binding: _Binding, words: Sequence[str]) -> Any:
        f = binding.field
        row_words = int(f.fixed.get("ROW_WORDS") or 1)
        return unpack_table(f.columns, row_words, [int(w, 0) for w in words])

    def _on_state(self, connected: bool, message: str) -> None:
        assert self._registrar is not None
        if connected:
            self._registrar.report_health(None)
            # the first poll after a reconnection sets every value and alarm
            return
        text = f"{self.box.address}: {message or 'connection lost'}"
        for b in self.bindings.values():
            b.attr.set_alarm(Alarm.disconnected(text))
        self._registrar.report_health(text)

    # ---- attributes -> the box
    def _putter(self, name: str) -> Callable[[Any], Any]:
        async def put(value: Any) -> None:
            b = self.bindings[name]
            if b.is_table:
                f = b.field
                row_words = int(f.fixed.get("ROW_WORDS") or 1)
                words = (
                    list(value)
                    if isinstance(value, RawWords)
                    else pack_table(f.columns, row_words, value)
                )
                try:
                    back = await self.box.write_table(b.target, words)
                except Zebra2Error as e:
                    raise self._refused(b.target, f"{len(words)} words", e) from None
                new = unpack_table(f.columns, row_words, back)
            else:
                text = _to_text(b.attr.meta, value)
                try:
                    back_text = await self.box.write(b.target, text)
                except Zebra2Error as e:
                    raise self._refused(b.target, text, e) from None
                new = value if back_text is None else _from_text(b.attr.meta, back_text)
            b.attr.set_value(b.attr.validate(new), alarm=Alarm.ok, validate=False)

        return put

    async def _send(self, command: str, target: str) -> None:
        try:
            await self.box.call(command)
        except Zebra2Error as e:
            raise self._refused(target, command.partition("=")[2], e) from None

    def _refused(self, target: str, text: str, e: Zebra2Error) -> BadValueError:
        mri = self._registrar.mri if self._registrar else self.instance
        return Zebra2Error(
            f"{mri}: the box refused {target}={text[:60]}", f"ERR {e.text}"
        )

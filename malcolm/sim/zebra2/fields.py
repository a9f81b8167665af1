"""The state of one field of one block instance, by field type.

Each class reads and writes its value and attributes with the server's
parsing and error texts, and tells its owner (`Notify`) which reportable keys
(``PCOMP1.START``, ``PULSE1.DELAY.UNITS``, ``SEQ.TABLE<``) a write touched.
"""

from __future__ import annotations

import base64
import struct
from collections.abc import Callable

from .layout import FieldDef
from .lut import parse_lut
from .values import (
    TIME_UNITS,
    Zebra2Error,
    format_double,
    parse_bit,
    parse_double,
    parse_int,
    parse_integer,
    parse_uint,
    ticks_to_time,
    time_to_ticks,
)

Notify = Callable[[str], None]
Reply = str | list[str]

CAPTURE_VALUE_ONLY = ["No", "Value"]


class FieldState:
    """A field with no value (``write action``) and the common attributes."""

    readable = False
    writeable = False

    def __init__(self, name: str, fdef: FieldDef, notify: Notify) -> None:
        self.key = name  # e.g. "PCOMP1.START" (no number if single instance)
        self.fdef = fdef
        self.notify = notify
        self.attrs: dict[str, str] = {}
        for aname, adef in fdef.attrs.items():
            if "value" in adef.initial:
                self.attrs[aname] = adef.initial["value"]
        #: an error every read gives (tier 1's extension-server fields)
        self.broken: str | None = None
        err = fdef.initial.get("error")
        if err and err != "ERR Field not readable":
            self.broken = err[4:]

    # -- value -------------------------------------------------------------
    def read(self) -> Reply:
        if self.broken:
            raise Zebra2Error(self.broken)
        if not self.readable:
            raise Zebra2Error("Field not readable")
        return self._read()

    def _read(self) -> Reply:
        raise NotImplementedError

    def write(self, text: str) -> None:
        if self.broken:
            raise Zebra2Error(self.broken)
        if not self.writeable:
            raise Zebra2Error("Field not writeable")
        self._write(text)
        self.notify(self.key)

    def _write(self, text: str) -> None:
        if text:
            raise Zebra2Error("Unexpected character after input")

    # -- attributes --------------------------------------------------------
    def read_attr(self, name: str) -> Reply:
        if name not in self.fdef.attrs:
            raise Zebra2Error("No such attribute")
        if name == "INFO":
            return self.fdef.info
        return self._read_attr(name)

    def _read_attr(self, name: str) -> Reply:
        if name in self.attrs:
            return self.attrs[name]
        initial = self.fdef.attrs[name].initial
        if "values" in initial:
            return list(initial["values"])
        raise Zebra2Error(initial.get("error", "ERR Attribute not readable")[4:])

    def write_attr(self, name: str, text: str) -> None:
        if name not in self.fdef.attrs:
            raise Zebra2Error("No such attribute")
        self._write_attr(name, text)
        self.notify(f"{self.key}.{name}")

    def _write_attr(self, name: str, text: str) -> None:
        raise Zebra2Error("Attribute not writeable")


class ActionField(FieldState):
    """``write action``: an empty write, never reported."""

    writeable = True

    def write(self, text: str) -> None:
        if text:
            raise Zebra2Error("Unexpected character after input")


class NumberField(FieldState):
    """``param``/``read``/``write`` of ``uint``, ``int``, ``bit``."""

    def __init__(self, name: str, fdef: FieldDef, notify: Notify) -> None:
        super().__init__(name, fdef, notify)
        self.readable = fdef.type != "write"
        self.writeable = fdef.type != "read"
        initial = fdef.initial.get("value", "0")
        self.value = int(initial) if initial.lstrip("-").isdigit() else 0
        self.maximum = int(self.attrs.get("MAX", 0xFFFFFFFF))

    def _read(self) -> Reply:
        return str(self.value)

    def _write(self, text: str) -> None:
        subtype = self.fdef.subtype
        if subtype == "int":
            self.value = parse_int(text)
        elif subtype == "bit":
            self.value = parse_bit(text)
        else:
            self.value = parse_uint(text, self.maximum)

    def set_live(self, value: int) -> None:
        """Set by the simulation; reported only if it changed."""
        if value != self.value:
            self.value = value
            self.notify(self.key)


class EnumField(FieldState):
    """``param``/``read enum``, ``bit_mux``, ``pos_mux``: a label of a list."""

    ERRORS = {
        "bit_mux": "Invalid bit bus selection",
        "pos_mux": "Invalid position selection",
    }

    def __init__(self, name: str, fdef: FieldDef, notify: Notify) -> None:
        super().__init__(name, fdef, notify)
        self.readable = fdef.type != "write"
        self.writeable = fdef.type != "read"
        self.labels = fdef.enums or []
        self.value = fdef.initial.get("value", self.labels[0] if self.labels else "")

    def _read(self) -> Reply:
        return self.value

    def _write(self, text: str) -> None:
        if text not in self.labels:
            raise Zebra2Error(
                self.ERRORS.get(self.fdef.type, "Invalid enumeration value")
            )
        self.value = text

    def set_live(self, value: str) -> None:
        """Set by the simulation; reported only if it changed."""
        if value != self.value:
            self.value = value
            self.notify(self.key)

    def _write_attr(self, name: str, text: str) -> None:
        if name == "DELAY":
            delay = parse_uint(text)
            if delay > int(self.attrs.get("MAX_DELAY", "31")):
                raise Zebra2Error("Delay too long")
            self.attrs[name] = str(delay)
        else:
            super()._write_attr(name, text)


class TimeField(FieldState):
    """``time`` and ``param time``: 125 MHz ticks shown in ``UNITS``."""

    readable = writeable = True

    def __init__(self, name: str, fdef: FieldDef, notify: Notify) -> None:
        super().__init__(name, fdef, notify)
        self.ticks = 0
        self.max_ticks = (1 << 48) - 1 if fdef.type == "time" else 0xFFFFFFFF

    @property
    def units(self) -> str:
        return self.attrs.get("UNITS", "s")

    def _read(self) -> Reply:
        return ticks_to_time(self.ticks, self.units)

    def _write(self, text: str) -> None:
        self.ticks = time_to_ticks(text, self.units, self.max_ticks)

    def _read_attr(self, name: str) -> Reply:
        if name == "RAW":
            return str(self.ticks)
        return super()._read_attr(name)

    def _write_attr(self, name: str, text: str) -> None:
        if name == "UNITS":
            if text not in TIME_UNITS:
                raise Zebra2Error("Invalid time units")
            self.attrs["UNITS"] = text
            self.notify(self.key)  # the value is reported in the new units
        elif name == "RAW":
            ticks = parse_integer(text)
            if not 0 <= ticks <= self.max_ticks:
                raise Zebra2Error("Number out of range")
            self.ticks = ticks
            self.notify(self.key)
        else:
            super()._write_attr(name, text)


class LutField(FieldState):
    """``param lut``: the formula as written, its truth table in ``RAW``."""

    readable = writeable = True

    def __init__(self, name: str, fdef: FieldDef, notify: Notify) -> None:
        super().__init__(name, fdef, notify)
        self.text = fdef.initial.get("value", "0x00000000")
        self.raw = 0

    def _read(self) -> Reply:
        return self.text

    def _write(self, text: str) -> None:
        self.raw = parse_lut(text)
        self.text = text

    def _read_attr(self, name: str) -> Reply:
        if name == "RAW":
            return f"0x{self.raw:08X}"
        return super()._read_attr(name)


class BitOutField(FieldState):
    """``bit_out``: a live bit; ``CAPTURE_WORD``/``OFFSET`` say where PCAP has it."""

    readable = True

    def __init__(self, name: str, fdef: FieldDef, notify: Notify) -> None:
        super().__init__(name, fdef, notify)
        self.value = 0

    def _read(self) -> Reply:
        return str(self.value)

    def set_live(self, value: int) -> None:
        if value != self.value:
            self.value = value
            self.notify(self.key)


class PosOutField(FieldState):
    """``pos_out``: a live position with scaling, units and capture."""

    readable = True

    def __init__(self, name: str, fdef: FieldDef, notify: Notify) -> None:
        super().__init__(name, fdef, notify)
        self.value = 0
        self.capture_labels = fdef.attrs["CAPTURE"].enums or []

    def _read(self) -> Reply:
        return str(self.value)

    def set_live(self, value: int) -> None:
        if value != self.value:
            self.value = value
            self.notify(self.key)

    @property
    def scale(self) -> float:
        return float(self.attrs.get("SCALE", "1"))

    @property
    def offset(self) -> float:
        return float(self.attrs.get("OFFSET", "0"))

    def _read_attr(self, name: str) -> Reply:
        if name == "SCALED":
            return format_double(self.value * self.scale + self.offset)
        return super()._read_attr(name)

    def _write_attr(self, name: str, text: str) -> None:
        if name in ("SCALE", "OFFSET"):
            self.attrs[name] = format_double(parse_double(text))
        elif name == "UNITS":
            self.attrs[name] = text
        elif name == "CAPTURE":
            if text not in self.capture_labels:
                raise Zebra2Error(f'Unknown capture option "{text}"')
            self.attrs[name] = text
        else:
            super()._write_attr(name, text)


class ExtOutField(FieldState):
    """``ext_out``: not readable; only ``CAPTURE`` (``No``/``Value``) and ``BITS``."""

    def _write_attr(self, name: str, text: str) -> None:
        if name == "CAPTURE":
            if text not in CAPTURE_VALUE_ONLY:
                raise Zebra2Error("Invalid capture option")
            self.attrs[name] = text
        else:
            super()._write_attr(name, text)


class TableField(FieldState):
    """``table``: 32-bit words, fixed or (if supported) streaming writes."""

    readable = True

    def __init__(
        self, name: str, fdef: FieldDef, notify: Notify, streaming: bool
    ) -> None:
        super().__init__(name, fdef, notify)
        self.words: list[int] = []
        self.mode = "INIT"
        self.streaming = streaming
        self.row_words = int(self.attrs.get("ROW_WORDS", "1"))
        self.max_length = int(self.attrs.get("MAX_LENGTH", "0"))

    def _read(self) -> Reply:
        return [str(w) for w in self.words]

    def write(self, text: str) -> None:
        raise Zebra2Error("Field not writeable")

    def _read_attr(self, name: str) -> Reply:
        if name == "LENGTH":
            return str(len(self.words))
        if name == "MODE":
            return self.mode
        if name == "B":
            data = struct.pack(f"<{len(self.words)}I", *self.words)
            return [
                base64.b64encode(data[i : i + 192]).decode()
                for i in range(0, len(data), 192)
            ]
        return super()._read_attr(name)

    def write_table(self, words: list[int], stream: bool, last: bool) -> None:
        """Apply a ``<`` (or ``<<``, ``<<|``) write; unchanged on error."""
        if stream and not self.streaming:
            raise Zebra2Error("Table do not support streaming mode")
        if self.mode == "STREAMING_LAST" and words:
            raise Zebra2Error("Last streaming table was sent")
        if stream:
            if not words:
                raise Zebra2Error("Streaming table must have data")
        elif self.mode == "STREAMING" and words:
            raise Zebra2Error("Table is in streaming mode")
        if len(words) % self.row_words:
            raise Zebra2Error("Table write is not a whole number of rows")
        if len(words) > self.max_length:
            raise Zebra2Error("Too many points for table")
        if stream:
            self.words = []
            self.mode = "STREAMING_LAST" if last else "STREAMING"
        else:
            self.words = list(words)
            self.mode = "FIXED" if words else "INIT"
        self.notify(self.key + "<")


def make_field(
    name: str, fdef: FieldDef, notify: Notify, streaming: bool
) -> FieldState:
    """The state class for a field's type."""
    t, sub = fdef.type, fdef.subtype
    if t == "table":
        return TableField(name, fdef, notify, streaming)
    if t in ("bit_mux", "pos_mux") or sub == "enum":
        return EnumField(name, fdef, notify)
    if t == "time" or sub == "time":
        return TimeField(name, fdef, notify)
    if sub == "lut":
        return LutField(name, fdef, notify)
    if t == "bit_out":
        return BitOutField(name, fdef, notify)
    if t == "pos_out":
        return PosOutField(name, fdef, notify)
    if t == "ext_out":
        return ExtOutField(name, fdef, notify)
    if sub in ("uint", "int", "bit"):
        return NumberField(name, fdef, notify)
    if sub == "action":
        return ActionField(name, fdef, notify)
    return FieldState(name, fdef, notify)

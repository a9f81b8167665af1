"""Parsing and printing of field values as the PandA server does it.

Numbers are parsed like C ``strtoul``/``strtod`` (base 0: ``0x`` hex, a
leading ``0`` octal, leading spaces and ``+``/``-`` accepted, nothing after
the number); doubles are printed with ``%.12g``.  Every parse error is a
`Zebra2Error` carrying the server's message.
"""

from __future__ import annotations

import re

CLOCK_HZ = 125_000_000
#: seconds per unit of a time field's UNITS
TIME_UNITS = {"min": 60.0, "s": 1.0, "ms": 1e-3, "us": 1e-6}

_UINT = re.compile(r"\s*([+-]?)(0[xX][0-9a-fA-F]+|0[0-7]*|[1-9][0-9]*)")
_DOUBLE = re.compile(
    r"\s*[+-]?(?:(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?|inf|nan)",
    re.IGNORECASE,
)


class Zebra2Error(Exception):
    """A command failed: ``str(e)`` is the text after ``ERR``."""


def parse_integer(text: str) -> int:
    """An integer as ``strtoul(text, &end, 0)`` reads it, sign applied."""
    m = _UINT.match(text)
    if not m:
        raise Zebra2Error("Number missing")
    if m.end() != len(text):
        raise Zebra2Error("Unexpected character after input")
    sign, digits = m.groups()
    if digits.startswith(("0x", "0X")):
        value = int(digits, 16)
    elif digits.startswith("0"):
        value = int(digits, 8)
    else:
        value = int(digits)
    if value >= 1 << 64:
        raise Zebra2Error("Number out of range")
    return -value if sign == "-" else value


def parse_uint(text: str, maximum: int = 0xFFFFFFFF) -> int:
    """A 32-bit unsigned value: wraps if unbounded, else checked against MAX."""
    value = parse_integer(text) % (1 << 32)
    if maximum != 0xFFFFFFFF and value > maximum:
        raise Zebra2Error("Number out of range")
    return value


def to_int32(value: int) -> int:
    """Wrap to a signed 32-bit integer."""
    value %= 1 << 32
    return value - (1 << 32) if value >= 1 << 31 else value


def parse_int(text: str) -> int:
    """A 32-bit signed value, wrapping."""
    return to_int32(parse_integer(text))


def parse_double(text: str) -> float:
    """A double as ``strtod`` reads it."""
    m = _DOUBLE.match(text)
    if not m:
        raise Zebra2Error("Number missing")
    if m.end() != len(text):
        raise Zebra2Error("Unexpected character after input")
    return float(m.group(0))


def format_double(value: float) -> str:
    """A double printed as the server prints it (``%.12g``)."""
    if value != value:
        return "nan"
    return f"{value:.12g}"


def parse_bit(text: str) -> int:
    """``0`` or ``1``."""
    value = parse_integer(text)
    if value not in (0, 1):
        raise Zebra2Error("Invalid bit value")
    return value


def time_to_ticks(text: str, units: str, max_ticks: int) -> int:
    """A time in ``units`` as whole 125 MHz ticks (below one tick is 0)."""
    seconds = parse_double(text) * TIME_UNITS[units]
    ticks = seconds * CLOCK_HZ
    if not ticks >= 0 or ticks > max_ticks:
        raise Zebra2Error("Time setting out of range")
    return int(ticks + 0.5)


def ticks_to_time(ticks: int, units: str) -> str:
    """Ticks printed in ``units``."""
    if ticks == 0:
        return "0"
    return format_double(ticks / CLOCK_HZ / TIME_UNITS[units])

"""Pieces of the control-port syntax: names, value replies, UTF-8 checks."""

from __future__ import annotations

import re
from dataclasses import dataclass

from .values import Zebra2Error

MAX_VALUE = 255
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_NUMBERED = re.compile(r"([A-Za-z_][A-Za-z0-9_]*?)([0-9]*)")

Reply = list[str]


def ok_value(value: str | list[str]) -> Reply:
    """A value reply: ``OK =v`` or a ``!`` list."""
    if isinstance(value, list):
        return [f"!{v}" for v in value] + ["."]
    if len(value) > MAX_VALUE:
        raise Zebra2Error("Result too long")
    return [f"OK ={value}"]


@dataclass
class Entity:
    """A parsed ``B[n][.F[.A]]`` name."""

    block: str
    number: str
    field: str | None
    attr: str | None


def parse_entity(text: str) -> Entity:
    """``B[n][.F[.A]]`` or ``B[n].*``/``B.F.*``; errors as the server's."""
    parts = text.split(".")
    if len(parts) > 3:
        raise Zebra2Error("Unexpected character after input")
    for i, part in enumerate(parts):
        if part == "*" and i == len(parts) - 1 and i > 0:
            continue
        m = _NAME.match(part)
        if not m:
            raise Zebra2Error("No name found")
        if m.end() != len(part):
            raise Zebra2Error("Unexpected character after input")
    m = _NUMBERED.fullmatch(parts[0])
    assert m
    block, number = m.groups()
    return Entity(
        block,
        number,
        parts[1] if len(parts) > 1 else None,
        parts[2] if len(parts) > 2 else None,
    )


def check_utf8(text: str) -> None:
    """Refuse text that is not valid UTF-8 (metadata values)."""
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        raise Zebra2Error("Malformed UTF-8 encoding") from None

"""LUT formulas: ``A&B|~C`` to the 32-bit truth table in ``FUNC.RAW``.

Inputs ``A``..``E`` are bits 4..0 of the table index.  Operators from
loosest to tightest: ``?:``, ``=``, ``=>``, ``|``, ``^``, ``&``, ``~``;
parentheses and the constants ``0``/``1`` are accepted, and a number of more
than one digit (``0x00000000``) is taken as the raw truth table itself.
"""

from __future__ import annotations

import re

from .values import Zebra2Error

_TOKEN = re.compile(r"\s*(=>|0[xX][0-9a-fA-F]+|[0-9]+|[A-E]|[~&|^=?:()])")
_ALL = 0xFFFFFFFF
_INPUTS = {
    name: sum(1 << i for i in range(32) if (i >> (4 - k)) & 1)
    for k, name in enumerate("ABCDE")
}


def _tokens(text: str) -> list[str]:
    tokens, pos = [], 0
    while pos < len(text):
        if text[pos:].strip() == "":
            break
        m = _TOKEN.match(text, pos)
        if not m:
            raise Zebra2Error("Invalid token")
        tokens.append(m.group(1))
        pos = m.end()
    return tokens


class _Parser:
    def __init__(self, tokens: list[str]) -> None:
        self.tokens = tokens
        self.pos = 0

    def peek(self) -> str | None:
        return self.tokens[self.pos] if self.pos < len(self.tokens) else None

    def take(self) -> str | None:
        token = self.peek()
        self.pos += 1
        return token

    def ternary(self) -> int:
        cond = self.binary(0)
        if self.peek() == "?":
            self.take()
            yes = self.ternary()
            if self.take() != ":":
                raise Zebra2Error("Missing value")
            no = self.ternary()
            return (cond & yes) | (~cond & no & _ALL)
        return cond

    _LEVELS = ("=", "=>", "|", "^", "&")

    def binary(self, level: int) -> int:
        if level == len(self._LEVELS):
            return self.unary()
        op = self._LEVELS[level]
        left = self.binary(level + 1)
        while self.peek() == op:
            self.take()
            right = self.binary(level + 1)
            if op == "=":
                left = ~(left ^ right) & _ALL
            elif op == "=>":
                left = (~left | right) & _ALL
            elif op == "|":
                left |= right
            elif op == "^":
                left ^= right
            else:
                left &= right
        return left

    def unary(self) -> int:
        token = self.take()
        if token == "~":
            return ~self.unary() & _ALL
        if token == "(":
            value = self.ternary()
            if self.take() != ")":
                raise Zebra2Error("Missing value")
            return value
        if token in _INPUTS:
            return _INPUTS[token]
        if token is not None and token[0].isdigit():
            if token in ("0", "1"):
                return _ALL if token == "1" else 0
            return int(token, 0) & _ALL
        raise Zebra2Error("Missing value")


def parse_lut(text: str) -> int:
    """The truth table of a formula, or `Zebra2Error` with the server's text."""
    parser = _Parser(_tokens(text))
    value = parser.ternary()
    if parser.peek() is not None:
        raise Zebra2Error("Invalid token")
    return value

"""The simulated position plugin's positions: parsed from NDPosPlugin XML and
kept until frames take them.

The XML a DetectorManager sends (``malcolm.parts.adcore.positions_xml``: one
dimension, ``<position n="i"/>`` back to back) is read by splitting the text,
with no element or dict per position; any other text goes through
ElementTree, which also rejects XML that is not well formed
(``ET.ParseError``, the buffer unchanged).
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from collections import deque

#: the manager's layout up to the first position: its one dimension's name
_HEAD = re.compile(
    r'<pos_layout><dimensions><dimension name="([A-Za-z_][\w.-]*)"/>'
    r"</dimensions><positions>"
)
_TAIL = "</positions></pos_layout>"
#: a character that an attribute value of the fast form never holds
_MARKUP = re.compile(r'["<>&\x00-\x1f\ufffe\uffff]')


class PositionBuffer:
    """The positions still to tag frames with, oldest first.

    Each load is kept as one segment (its attribute names and a list of
    values, or a list of dicts); :meth:`popleft` makes the dict of one
    position when a frame takes it.
    """

    def __init__(self) -> None:
        self._segments: deque[tuple[str | None, list]] = deque()
        self._first = 0  # positions of the first segment already taken
        self._len = 0

    def __len__(self) -> int:
        return self._len

    def __bool__(self) -> bool:
        return self._len > 0

    def clear(self) -> None:
        self._segments.clear()
        self._first = 0
        self._len = 0

    def extend(self, name: str | None, rows: list) -> None:
        """Add positions: ``rows`` of values of attribute ``name``, or (name
        None) of dicts of attributes."""
        if rows:
            self._segments.append((name, rows))
            self._len += len(rows)

    def popleft(self) -> dict[str, str]:
        """The oldest position (IndexError if none)."""
        if not self._len:
            raise IndexError("no positions")
        name, rows = self._segments[0]
        row = rows[self._first]
        self._first += 1
        self._len -= 1
        if self._first == len(rows):
            self._segments.popleft()
            self._first = 0
        return dict(row) if name is None else {name: row}


def _fast(text: str) -> tuple[str, list[str]] | None:
    """The dimension name and values of the manager's form of XML, or None
    if ``text`` is not exactly that form."""
    head = _HEAD.match(text)
    if head is None or not text.endswith(_TAIL):
        return None
    name = head.group(1)
    body = text[head.end() : len(text) - len(_TAIL)]
    if not body:
        return name, []
    opening = f'<position {name}="'
    if not (body.startswith(opening) and body.endswith('"/>')):
        return None
    inner = body[len(opening) : -3]
    separator = f'"/>{opening}'
    if _MARKUP.search(inner.replace(separator, "")):
        return None
    return name, inner.split(separator)


def parse_positions(text: str, buffer: PositionBuffer) -> int:
    """Append the positions of NDPosPlugin XML ``text`` to ``buffer``;
    returns how many. Raises ``ET.ParseError`` (buffer unchanged) for text
    that is not well-formed XML."""
    fast = _fast(text)
    if fast is not None:
        name, values = fast
        buffer.extend(name, values)
        return len(values)
    root = ET.fromstring(text)
    rows = [dict(position.attrib) for position in root.iter("position")]
    buffer.extend(None, rows)
    return len(rows)

"""The simulated position plugin's XML loading (malcolm.sim.beamline_ioc
.positions): the manager's XML read without ElementTree gives exactly what
ElementTree gives; anything else still goes through ElementTree."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import pytest
from hypothesis import given
from hypothesis import strategies as st

from malcolm.parts.adcore import positions_xml
from malcolm.sim.beamline_ioc.positions import (
    PositionBuffer,
    _fast,
    parse_positions,
)


def by_elementtree(text: str) -> list[dict[str, str]]:
    return [dict(p.attrib) for p in ET.fromstring(text).iter("position")]


def drain(buffer: PositionBuffer) -> list[dict[str, str]]:
    out = []
    while buffer:
        out.append(buffer.popleft())
    return out


@pytest.mark.parametrize("start,stop", [(0, 0), (0, 1), (7, 2507), (9990, 10000)])
def test_manager_xml_takes_the_fast_path_and_matches_elementtree(start, stop):
    text = positions_xml(start, stop)
    assert _fast(text) is not None
    buffer = PositionBuffer()
    assert parse_positions(text, buffer) == stop - start
    assert len(buffer) == stop - start
    assert drain(buffer) == by_elementtree(text)


@pytest.mark.parametrize(
    "text",
    [
        # whitespace, a second attribute, two dimensions, an entity, a tab
        # in a value (XML makes it a space): not the manager's form
        '<pos_layout>\n<dimensions><dimension name="n"/></dimensions>'
        '<positions><position n="1"/></positions></pos_layout>',
        '<pos_layout><dimensions><dimension name="n"/></dimensions>'
        '<positions><position n="1" x="2"/></positions></pos_layout>',
        '<pos_layout><dimensions><dimension name="x"/><dimension name="y"/>'
        '</dimensions><positions><position x="1" y="2"/><position x="3" y="4"/>'
        "</positions></pos_layout>",
        '<pos_layout><dimensions><dimension name="n"/></dimensions>'
        '<positions><position n="a&amp;b"/></positions></pos_layout>',
        '<pos_layout><dimensions><dimension name="n"/></dimensions>'
        '<positions><position n="1\t2"/></positions></pos_layout>',
        '<pos_layout><dimensions><dimension name="n"/></dimensions>'
        '<positions><position n="1"/><position m="2"/></positions></pos_layout>',
    ],
)
def test_other_xml_goes_through_elementtree(text):
    assert _fast(text) is None
    buffer = PositionBuffer()
    assert parse_positions(text, buffer) == len(by_elementtree(text))
    assert drain(buffer) == by_elementtree(text)


@pytest.mark.parametrize(
    "text",
    [
        "",
        "not xml",
        '<pos_layout><dimensions><dimension name="n"/></dimensions>'
        '<positions><position n="1"/><position n="2"</positions></pos_layout>',
        '<pos_layout><dimensions><dimension name="n"/></dimensions>'
        '<positions><position n="1"/></positions></pos_layou>',
        '<pos_layout><dimensions><dimension name="n"/></dimensions>'
        '<positions><position n="1"2"/></positions></pos_layout>',
    ],
)
def test_bad_xml_is_rejected_and_the_buffer_kept(text):
    buffer = PositionBuffer()
    parse_positions(positions_xml(0, 3), buffer)
    with pytest.raises(ET.ParseError):
        parse_positions(text, buffer)
    assert drain(buffer) == [{"n": "0"}, {"n": "1"}, {"n": "2"}]


def test_loads_queue_in_order_and_clear_empties():
    buffer = PositionBuffer()
    parse_positions(positions_xml(0, 2), buffer)
    parse_positions(
        '<pos_layout><positions><position x="5" y="6"/></positions></pos_layout>',
        buffer,
    )
    parse_positions(positions_xml(2, 4), buffer)
    assert len(buffer) == 5
    assert buffer.popleft() == {"n": "0"}
    assert len(buffer) == 4
    assert drain(buffer) == [{"n": "1"}, {"x": "5", "y": "6"}, {"n": "2"}, {"n": "3"}]
    with pytest.raises(IndexError):
        buffer.popleft()
    parse_positions(positions_xml(0, 5), buffer)
    buffer.popleft()
    buffer.clear()
    assert not buffer and len(buffer) == 0
    parse_positions(positions_xml(8, 9), buffer)
    assert drain(buffer) == [{"n": "8"}]


_value = st.text(
    alphabet=st.characters(blacklist_categories=("Cs",), max_codepoint=0x2FF),
    max_size=6,
)


@given(st.lists(_value, max_size=8))
def test_any_values_read_as_elementtree_reads_them(values):
    """Values of any characters (quotes, markup, control characters) in the
    manager's layout: the fast path takes only what it reads as ElementTree
    does, and a text ElementTree rejects is rejected either way."""
    rows = "".join(f'<position n="{v}"/>' for v in values)
    text = (
        '<pos_layout><dimensions><dimension name="n"/></dimensions>'
        f"<positions>{rows}</positions></pos_layout>"
    )
    try:
        expected = by_elementtree(text)
    except ET.ParseError:
        with pytest.raises(ET.ParseError):
            parse_positions(text, PositionBuffer())
        return
    buffer = PositionBuffer()
    parse_positions(text, buffer)
    assert drain(buffer) == expected

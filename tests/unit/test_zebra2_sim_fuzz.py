"""Bad input never breaks the simulated box: any line gets exactly one
well-formed reply (after the empty line that ends a table write), and the
box still answers correctly afterwards.  Also the value parsers and LUT
formulas beyond what the transcripts show.
"""

from __future__ import annotations

import re

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from malcolm.sim.zebra2 import ManualClock, load_layout
from malcolm.sim.zebra2.box import Box
from malcolm.sim.zebra2.commands import Session
from malcolm.sim.zebra2.lut import parse_lut
from malcolm.sim.zebra2.simulation import Simulation
from malcolm.sim.zebra2.values import (
    Zebra2Error,
    parse_int,
    parse_uint,
    ticks_to_time,
    time_to_ticks,
)

_REPLY = re.compile(r"^(OK|OK =.*|ERR .+)$")
LAYOUT = load_layout("tier2")

pieces = st.sampled_from(
    [
        "*", "PCOMP", "PCOMP1", "SEQ", "SEQ1", "CLOCK1", "PCAP", ".", "START",
        "TABLE", "ENABLE", "UNITS", "DELAY", "CAPTURE", "?", "=", "<", "<<", "|",
        "B", " ", "0x1f", "-1", "1e9", "CHANGES", "METADATA", "PCAP.ARM",
        "DESC", "ENUMS", "[]", "ONE", "Min Max", "\r", "\xff", "é", "*ECHO ",
    ]
)  # fmt: skip
lines = st.lists(pieces, max_size=8).map("".join)


def new_session() -> Session:
    box = Box(LAYOUT)
    return Session(box, Simulation(box, ManualClock()))


def assert_reply(reply: list[str]) -> None:
    if len(reply) == 1 and not reply[0].startswith("!") and reply[0] != ".":
        assert _REPLY.match(reply[0]), reply
    else:
        assert reply[-1] == "." and all(r.startswith("!") for r in reply[:-1])


@settings(max_examples=300, deadline=None)
@given(st.lists(lines, min_size=1, max_size=12))
def test_any_lines_get_one_wellformed_reply_each(sent: list[str]) -> None:
    session = new_session()
    for line in sent:
        reply = session.feed_line(line)
        if reply is not None:
            assert_reply(reply)
            assert not reply[0].startswith("ERR Internal")
    if session.table is not None:  # end a table write left open
        reply = session.feed_line("")
        assert reply is not None
        assert_reply(reply)
    assert session.feed_line("*IDN?") == [f"OK ={LAYOUT.idn}"]
    assert session.feed_line("*ECHO still here?") == ["OK =still here"]


def test_failed_writes_change_nothing() -> None:
    session = new_session()
    session.feed_line("*CHANGES?")
    for line in [
        "PCOMP1.START=abc",
        "PCOMP1.DIR=Sideways",
        "PCOMP1.ENABLE=NOTHING",
        "CLOCK1.PERIOD=-1",
        "CLOCK1.PERIOD.UNITS=hours",
        "COUNTER1.OUT.CAPTURE=Bogus",
        "PCAP.SHIFT_SUM=9",
    ]:
        assert session.feed_line(line)[0].startswith("ERR "), line
    for line in ["SEQ.TABLE<", "1 2 3", ""]:
        reply = session.feed_line(line)
    assert reply == ["ERR Table write is not a whole number of rows"]
    assert session.feed_line("*CHANGES?") == ["."]


@pytest.mark.parametrize(
    "text, value",
    [("0x10", 16), ("010", 8), ("+7", 7), (" 7", 7), ("-1", 0xFFFFFFFF),
     ("4294967296", 0), ("99999999999", 1215752191), ("0", 0)],
)  # fmt: skip
def test_uint_parsing(text: str, value: int) -> None:
    assert parse_uint(text) == value


@pytest.mark.parametrize(
    "text, error",
    [("", "Number missing"), ("abc", "Number missing"), ("7 ", "Unexpected"),
     ("1.5", "Unexpected"), ("08", "Unexpected"), ("0x", "Unexpected"),
     ("1" * 25, "Number out of range")],
)  # fmt: skip
def test_uint_errors(text: str, error: str) -> None:
    with pytest.raises(Zebra2Error, match=error):
        parse_uint(text)


def test_int_wraps_and_bounded_uint_checks() -> None:
    assert parse_int("2147483648") == -2147483648
    assert parse_int("-5") == -5
    with pytest.raises(Zebra2Error, match="Number out of range"):
        parse_uint("9", maximum=8)


def test_time_units_and_ticks() -> None:
    assert time_to_ticks("2.5", "ms", 2**32) == 312500
    assert time_to_ticks("0.000000001", "s", 2**32) == 0
    assert ticks_to_time(312500, "us") == "2500"
    assert ticks_to_time(7, "s") == "5.6e-08"
    with pytest.raises(Zebra2Error, match="Time setting out of range"):
        time_to_ticks("1e20", "s", 2**48)


@pytest.mark.parametrize(
    "formula, raw",
    [("A&B|~C", 0xFF0F0F0F), ("A", 0xFFFF0000), ("E", 0xAAAAAAAA),
     ("~(A|B)", 0x000000FF), ("A^B", 0x00FFFF00), ("A=B", 0xFF0000FF),
     ("A=>B", 0xFF00FFFF), ("A?B:C", 0xFF00F0F0), ("1", 0xFFFFFFFF),
     ("0x00000000", 0)],
)  # fmt: skip
def test_lut_formulas(formula: str, raw: int) -> None:
    assert parse_lut(formula) == raw


@pytest.mark.parametrize(
    "formula, error",
    [("A&&B", "Missing value"), ("F", "Invalid token"), ("(A", "Missing value"),
     ("A B", "Invalid token"), ("", "Missing value")],
)  # fmt: skip
def test_lut_errors(formula: str, error: str) -> None:
    with pytest.raises(Zebra2Error, match=error):
        parse_lut(formula)

"""io/ca/link.py's _unpack: one number in its TIME form read from its
struct at once gives what pyepics' own unpacking gives."""

from __future__ import annotations

import ctypes
from types import SimpleNamespace
from typing import Any

import pytest
from epics import ca, dbr

from malcolm.io.ca import link

CASES = [
    (dbr.TIME_DOUBLE, 0.1 + 1e-9),
    (dbr.TIME_DOUBLE, -1e300),
    (dbr.TIME_FLOAT, 0.1),  # float32: the same rounding both ways
    (dbr.TIME_LONG, -123456789),
    (dbr.TIME_INT, -300),
    (dbr.TIME_ENUM, 3),
]


def event(ftype: int, value: Any, severity: int) -> tuple[Any, SimpleNamespace]:
    struct = dbr.Map[ftype]()
    struct.status, struct.severity = 7 * severity, severity
    struct.stamp.secs, struct.stamp.nsec = 1_165_000_000, 123_456_789
    struct.value = value
    args = SimpleNamespace(
        type=ftype, count=1, raw_dbr=ctypes.addressof(struct), chid=None
    )
    return struct, args  # the struct kept alive while args point at it


@pytest.mark.parametrize(("ftype", "value"), CASES)
@pytest.mark.parametrize("severity", [0, 2])
def test_a_time_number_unpacks_as_pyepics_does(
    ftype: int, value: Any, severity: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    link._context()  # pyepics reads the value offsets from libca
    monkeypatch.setattr(ca, "element_count", lambda chid: 1)  # no channel here
    struct, args = event(ftype, value, severity)
    fast = link._unpack(args)
    assert fast is not None
    assert fast == link._unpack_any(args)
    assert type(fast[0]) is type(link._unpack_any(args)[0])
    assert fast[1]["severity"] == severity and fast[1]["nanoseconds"] == 123_456_789

"""The pyepics backend's conversions, without an IOC."""

import math

import numpy as np
import pytest
from epics import dbr

from malcolm.core import AlarmSeverity, AlarmStatus
from malcolm.io.ca.backend import alarm_of, info_of, timestamp_of
from malcolm.io.ca.link import _marshal


def test_alarms_name_the_epics_condition():
    assert alarm_of({"severity": 0, "status": 4}).severity is AlarmSeverity.NO_ALARM
    high = alarm_of({"severity": 1, "status": 4})
    assert (high.severity, high.status, high.message) == (
        AlarmSeverity.MINOR_ALARM,
        AlarmStatus.RECORD_STATUS,
        "HIGH",
    )
    link = alarm_of({"severity": 3, "status": 14})
    assert (link.status, link.message) == (AlarmStatus.DEVICE_STATUS, "LINK")
    assert alarm_of({"severity": 3, "status": 17}).status is (
        AlarmStatus.UNDEFINED_STATUS
    )
    assert alarm_of({"severity": 2, "status": 99}).message == "STAT 99"


def test_time_stamps_and_control_information():
    stamp = timestamp_of({"posixseconds": 1700000000.0, "nanoseconds": 5})
    assert (stamp.secondsPastEpoch, stamp.nanoseconds) == (1700000000, 5)
    md = {
        "lower_ctrl_limit": 0.0,
        "upper_ctrl_limit": 0.0,
        "lower_disp_limit": -5.0,
        "upper_disp_limit": 5.0,
        "units": "mm",
        "precision": 3,
    }
    # no drive limits (both 0): the display limits
    assert info_of(dbr.DOUBLE, md) == {
        "limits": (-5.0, 5.0),
        "units": "mm",
        "precision": 3,
    }
    assert info_of(dbr.LONG, {**md, "lower_disp_limit": math.nan}) == {"units": "mm"}
    assert info_of(dbr.ENUM, {"enum_strs": ("Off", "On")}) == {"choices": ("Off", "On")}
    assert info_of(dbr.STRING, md) == {}


def test_values_are_marshalled_for_the_native_type_or_refused():
    data, n = _marshal([1.5, 2.5], dbr.DOUBLE, 10)
    assert n == 2 and list(data) == [1.5, 2.5]
    data, n = _marshal(3.0, dbr.LONG, 1)
    assert n == 1 and data[0] == 3
    data, n = _marshal("text", dbr.STRING, 1)
    assert data[0].value == b"text"
    with pytest.raises(ValueError, match="not whole"):
        _marshal(2.5, dbr.LONG, 1)
    with pytest.raises(ValueError, match="not a number"):
        _marshal("abc", dbr.DOUBLE, 1)


def test_arrays_and_text_waveforms_are_marshalled_whole():
    positions = np.linspace(-1.0, 1.0, 20_001)
    data, n = _marshal(positions, dbr.DOUBLE, 50_000)
    assert n == 20_001 and np.array_equal(np.ctypeslib.as_array(data), positions)
    data, n = _marshal(positions[:5], dbr.DOUBLE, 3)  # cut to the PV's count
    assert n == 3 and list(data) == list(positions[:3])
    data, n = _marshal(np.array([4.0, -2.0]), dbr.LONG, 5)  # whole floats
    assert n == 2 and list(data) == [4, -2]
    text = np.frombuffer(b'<pos n="1"/>' + b"\0", dtype=np.uint8)
    data, n = _marshal(text, dbr.CHAR, 65_536)
    assert n == 13 and bytes(data) == b'<pos n="1"/>\0'
    data, n = _marshal([], dbr.DOUBLE, 10)  # nothing: one zero, as before
    assert n == 1 and list(data) == [0.0]
    with pytest.raises(ValueError, match="not whole"):
        _marshal(np.array([1.0, np.nan]), dbr.LONG, 5)


@pytest.mark.parametrize(
    "ftype", [dbr.SHORT, dbr.FLOAT, dbr.ENUM, dbr.CHAR, dbr.LONG, dbr.DOUBLE]
)
def test_a_python_number_is_marshalled_as_its_array_of_one_would_be(ftype):
    # the scalar path (ctypes alone) against the numpy path of the same value
    # given as a list: the same numbers, the same wrapping, the same refusals
    for value in (
        0, 1, -1, 255, 300, -300, 65536, 2**31, -(2**31) - 1, 2**40,
        True, False, 0.0, -0.0, 1.0, 2.5, -3.0, 1e10, 255.0, 2.0**40, 3.4e38,
    ):  # fmt: skip
        with np.errstate(all="ignore"):  # numpy's casts out of range
            try:
                scalar = list(_marshal(value, ftype, 1)[0])
            except ValueError as e:
                scalar = [str(e)]
            try:
                array = list(_marshal([value], ftype, 1)[0])
            except ValueError as e:
                array = [str(e).replace(repr([value]), repr(value))]
        assert scalar == array, (ftype, value)

"""NumberArrayMeta checks a 1-d numeric numpy array whole: the same values,
and the same errors (naming the element), as element by element."""

from __future__ import annotations

import numpy as np
import pytest

from malcolm.core import BadValueError, NumberArrayMeta
from malcolm.core.arrays import ArrayMeta


def slow(meta, value):
    return ArrayMeta.validate(meta, value)


CASES = [
    ("float64", np.linspace(-1, 1, 50), None),
    ("float64", np.arange(10, dtype=np.int32), None),
    ("float32", np.array([1.0, 3.5e38]), None),
    ("float64", np.array([0.5, 2.0]), {"limitLow": 0.0, "limitHigh": 1.0}),
    ("float64", np.array([0.5, np.nan]), {"limitLow": 0.0, "limitHigh": 1.0}),
    ("int32", np.array([1, 2, 3], dtype=np.int64), None),
    ("int32", np.array([1.0, 2.0]), None),
    ("int32", np.array([1.0, 2.5]), None),
    ("int32", np.array([1, 2**40]), None),
    ("uint8", np.array([-1, 2]), None),
    ("int32", np.array([np.inf]), None),
    ("int64", np.array([5, 7], dtype=np.uint64), None),
]


@pytest.mark.parametrize("dtype, value, display", CASES)
def test_the_whole_array_check_agrees_with_the_element_check(dtype, value, display):
    meta = NumberArrayMeta(dtype, display=display)
    try:
        expected = slow(meta, value)
    except BadValueError as e:
        with pytest.raises(BadValueError) as info:
            meta.validate(value)
        assert str(info.value) == str(e)
        return
    got = meta.validate(value)
    assert got == expected
    assert [type(v) for v in got] == [type(v) for v in expected]


def test_booleans_still_go_element_by_element_and_empty_is_empty():
    meta = NumberArrayMeta("int32")
    with pytest.raises(BadValueError, match=r"\[0\]"):
        meta.validate(np.array([True, False]))
    assert meta.validate(np.array([], dtype=float)) == ()

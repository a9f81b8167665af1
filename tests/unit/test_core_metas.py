"""Validation by the metas: canonical values, and errors that say what and where."""

import math

import numpy as np
import pytest

from malcolm.core import (
    BadValueError,
    BooleanArrayMeta,
    BooleanMeta,
    ChoiceArrayMeta,
    ChoiceMeta,
    MapMeta,
    MethodMeta,
    NumberArray,
    NumberArrayMeta,
    NumberMeta,
    StringArrayMeta,
    StringMeta,
    TableMeta,
)
from malcolm.core.metas import INT_RANGES, plain

# ---- numbers


@pytest.mark.parametrize("dtype", sorted(INT_RANGES))
def test_int_dtype_limits_are_inclusive(dtype):
    lo, hi = INT_RANGES[dtype]
    meta = NumberMeta(dtype)
    assert meta.validate(lo) == lo
    assert meta.validate(hi) == hi
    with pytest.raises(BadValueError, match=f"out of range for {dtype}"):
        meta.validate(hi + 1)
    with pytest.raises(BadValueError, match=f"out of range for {dtype}"):
        meta.validate(lo - 1)


def test_int_dtype_takes_integral_floats_and_rejects_fractions():
    meta = NumberMeta("int32")
    value = meta.validate(5.0)
    assert value == 5 and type(value) is int
    with pytest.raises(BadValueError, match=r"expected an integer \(int32\), got 5.5"):
        meta.validate(5.5)
    with pytest.raises(BadValueError, match="expected an integer"):
        meta.validate(math.inf)
    with pytest.raises(BadValueError, match="expected an integer"):
        meta.validate(math.nan)


def test_float_dtype_gives_floats():
    meta = NumberMeta("float64")
    value = meta.validate(3)
    assert value == 3.0 and type(value) is float


@pytest.mark.parametrize(
    "dtype, text, expected",
    [
        ("int32", "12", 12),
        ("int32", " 12 ", 12),
        ("int32", "-7", -7),
        ("int32", "0x10", 16),
        ("int32", "010", 10),
        ("int32", "5.0", 5),
        ("uint8", "255", 255),
        ("float64", "2.5", 2.5),
        ("float64", "1e3", 1000.0),
        ("float32", "-0.25", -0.25),
    ],
)
def test_numbers_from_strings(dtype, text, expected):
    value = NumberMeta(dtype).validate(text)
    assert value == expected and type(value) is type(expected)


@pytest.mark.parametrize(
    "dtype, value, message",
    [
        ("int32", "five", r"expected a number \(int32\), got 'five'"),
        ("float64", "", r"expected a number \(float64\)"),
        ("int32", "5.5", r"expected an integer \(int32\), got 5.5"),
        ("uint8", "256", r"256 is out of range for uint8 \[0, 255\]"),
        ("int32", True, r"expected a number \(int32\), got True"),
        ("float64", None, r"expected a number \(float64\), got None"),
        ("float64", [1.0], r"expected a number"),
        ("float64", 10**400, "out of range for float64"),
        ("float32", 1e39, "out of range for float32"),
    ],
)
def test_bad_numbers(dtype, value, message):
    with pytest.raises(BadValueError, match=message):
        NumberMeta(dtype).validate(value)


def test_numpy_numbers():
    assert NumberMeta("int8").validate(np.int64(-3)) == -3
    assert type(NumberMeta("int8").validate(np.int64(-3))) is int
    assert NumberMeta("float64").validate(np.float32(0.5)) == 0.5
    with pytest.raises(BadValueError, match="out of range"):
        NumberMeta("uint8").validate(np.int16(300))
    with pytest.raises(BadValueError, match="expected a number"):
        NumberMeta("float64").validate(np.array([1.0, 2.0]))
    with pytest.raises(BadValueError, match="expected a number"):
        NumberMeta("int32").validate(np.bool_(True))


def test_unknown_dtype():
    with pytest.raises(BadValueError, match="unknown dtype 'int7'"):
        NumberMeta("int7")
    with pytest.raises(BadValueError, match="unknown dtype"):
        NumberArrayMeta("complex")


def test_display_limits():
    meta = NumberMeta("float64", display={"limitLow": 0.0, "limitHigh": 10.0})
    assert meta.validate(10) == 10.0
    with pytest.raises(BadValueError, match=r"outside the limits \[0.0, 10.0\]"):
        meta.validate(10.5)
    # equal limits mean "no limits", as in EPICS
    assert NumberMeta(display={"limitLow": 0, "limitHigh": 0}).validate(-5) == -5.0


# ---- strings, booleans, choices


def test_strings():
    meta = StringMeta()
    assert meta.validate("x") == "x"
    assert meta.validate(None) == ""
    with pytest.raises(BadValueError, match="expected a string, got 5"):
        meta.validate(5)


@pytest.mark.parametrize(
    "value, expected",
    [
        (True, True),
        (False, False),
        (1, True),
        (0, False),
        ("Yes", True),
        ("no", False),
        ("TRUE", True),
        ("false", False),
        ("on", True),
        ("Off", False),
        ("1", True),
        ("0", False),
        (" yes ", True),
        (np.bool_(True), True),
        (np.int32(0), False),
    ],
)
def test_booleans(value, expected):
    assert BooleanMeta().validate(value) is expected


@pytest.mark.parametrize("value", [2, -1, "maybe", "", None, 0.5, [True]])
def test_bad_booleans(value):
    with pytest.raises(BadValueError, match="expected a boolean"):
        BooleanMeta().validate(value)


def test_choices_by_name_and_index():
    meta = ChoiceMeta(["Ready", "Fault", "Disabled"])
    assert meta.validate("Fault") == "Fault"
    assert meta.validate(2) == "Disabled"
    assert meta.validate(np.int64(0)) == "Ready"
    assert meta.validate(None) == "Ready"
    assert meta.default() == "Ready"


@pytest.mark.parametrize("value", ["ready", 3, -1, True, 1.0, ""])
def test_bad_choices_list_the_choices(value):
    with pytest.raises(BadValueError, match="is not one of Ready, Fault"):
        ChoiceMeta(["Ready", "Fault"]).validate(value)


def test_choices_none_given():
    with pytest.raises(BadValueError, match=r"not one of \(none\)"):
        ChoiceMeta([]).validate("x")
    # the default of a meta always validates, even with no choices (yet)
    assert ChoiceMeta([]).validate(ChoiceMeta([]).default()) == ""
    assert ChoiceMeta([]).validate(None) == ""


# ---- arrays


def test_arrays_validate_each_element_and_give_tuples():
    assert NumberArrayMeta("int16").validate([1, 2.0, "3"]) == (1, 2, 3)
    assert NumberArrayMeta("float64").validate(np.arange(3)) == (0.0, 1.0, 2.0)
    assert StringArrayMeta().validate(("a", "b")) == ("a", "b")
    assert BooleanArrayMeta().validate(["yes", 0, True]) == (True, False, True)
    assert ChoiceArrayMeta(["a", "b"]).validate(["b", 0]) == ("b", "a")
    assert NumberArrayMeta().validate(None) == ()


def test_array_errors_name_the_index():
    with pytest.raises(BadValueError, match=r"^\[2\]: 300 is out of range for uint8"):
        NumberArrayMeta("uint8").validate([1, 2, 300])
    with pytest.raises(BadValueError, match=r"^\[1\]: 'c' is not one of a, b"):
        ChoiceArrayMeta(["a", "b"]).validate(["a", "c"])


@pytest.mark.parametrize("value", ["abc", b"abc", 5, {"a": 1}, np.float64(1.0)])
def test_non_arrays(value):
    with pytest.raises(BadValueError, match="expected an array"):
        NumberArrayMeta().validate(value)


# ---- tables


def _table() -> TableMeta:
    return TableMeta(
        {
            "name": StringArrayMeta(label="Name"),
            "x": NumberArrayMeta("int32"),
            "on": BooleanArrayMeta(),
        }
    )


def test_table_by_columns():
    value = _table().validate({"name": ["a", "b"], "x": [1, 2.0], "on": [1, "no"]})
    assert value == {"name": ("a", "b"), "x": (1, 2), "on": (True, False)}


def test_table_by_rows_fills_missing_cells_with_defaults():
    value = _table().validate([{"name": "a", "x": 1}, {"x": "2", "on": "yes"}])
    assert value == {"name": ("a", ""), "x": (1, 2), "on": (False, True)}
    assert _table().rows(value) == [
        {"name": "a", "x": 1, "on": False},
        {"name": "", "x": 2, "on": True},
    ]


def test_table_missing_column_is_filled_and_typeid_ignored():
    value = _table().validate({"typeid": "malcolm:core/Table:1.0", "x": [4, 5]})
    assert value == {"name": ("", ""), "x": (4, 5), "on": (False, False)}
    assert _table().validate(None) == {"name": (), "x": (), "on": ()}
    assert _table().validate([]) == {"name": (), "x": (), "on": ()}


@pytest.mark.parametrize(
    "value, message",
    [
        ({"x": [1, 2, 3.5]}, r"^row 2, column x: expected an integer \(int32\)"),
        (
            {"x": [1], "name": ["a", "b"]},
            r"^column x has 1 rows, but column name has 2",
        ),
        ({"x": "12"}, r"^column x: expected an array"),
        ({"y": [1]}, r"^unknown column 'y' \(columns: name, x, on\)"),
        ([{"x": 1}, {"x": "a"}], r"^row 1, column x: expected a number"),
        ([{"x": 1}, {"z": 1}], r"^row 1: unknown column 'z'"),
        ([{"x": 1}, 5], r"^row 1: expected a mapping of column values"),
        ([{"on": "maybe"}], r"^row 0, column on: expected a boolean"),
        ("abc", "expected a table"),
    ],
)
def test_table_errors_name_row_and_column(value, message):
    with pytest.raises(BadValueError, match=message):
        _table().validate(value)


def test_table_columns_must_be_arrays():
    with pytest.raises(BadValueError, match="column x: a table column needs an array"):
        TableMeta({"x": NumberMeta()})


# ---- method arguments


def _method_meta() -> MethodMeta:
    return MethodMeta(
        MapMeta(
            {
                "exposure": NumberMeta("float64"),
                "frames": NumberMeta("uint32"),
                "axes": StringArrayMeta(),
                "name": StringMeta(),
            },
            required=["exposure"],
        ),
        defaults={"frames": 1, "axes": ["x", "y"]},
    )


def test_validate_args_converts_and_applies_defaults():
    args = _method_meta().validate_args("DET.configure", {"exposure": "0.1"})
    assert args == {"exposure": 0.1, "frames": 1, "axes": ("x", "y")}


def test_validate_args_none_means_not_given():
    args = _method_meta().validate_args("m", {"exposure": 1, "frames": None})
    assert args["frames"] == 1


def test_validate_args_defaults_are_copies():
    meta = MethodMeta(MapMeta({"d": MapMeta()}), defaults={"d": {"a": [1]}})
    args = meta.validate_args("m", {})
    args["d"]["a"].append(2)
    assert meta.defaults == {"d": {"a": [1]}}


@pytest.mark.parametrize(
    "args, message",
    [
        ({}, r"^DET.configure.exposure: missing required argument$"),
        (
            {"exposure": 1, "bogus": 2},
            r"^DET.configure.bogus: unknown argument \(takes exposure, frames, axes,",
        ),
        ({"exposure": "fast"}, r"^DET.configure.exposure: expected a number"),
        ({"exposure": 1, "frames": -1}, r"^DET.configure.frames: -1 is out of range"),
        ({"exposure": 1, "axes": "x"}, r"^DET.configure.axes: expected an array"),
        ({"exposure": 1, "axes": ["x", 2]}, r"^DET.configure.axes: \[1\]: expected a"),
        ({"exposure": 1, "name": 5}, r"^DET.configure.name: expected a string"),
        (["exposure"], r"^DET.configure: arguments must be a mapping"),
    ],
)
def test_validate_args_errors_name_method_and_arg(args, message):
    with pytest.raises(BadValueError, match=message):
        _method_meta().validate_args("DET.configure", args)


def test_validate_args_no_arguments():
    with pytest.raises(BadValueError, match=r"m.x: unknown argument \(takes no arg"):
        MethodMeta().validate_args("m", {"x": 1})
    assert MethodMeta().validate_args("m", {}) == {}


# ---- plain data


def test_plain_converts_tuples_and_numpy():
    value = plain({"a": (1, (2, 3)), "b": [np.int32(4)], "c": np.arange(2)})
    assert value == {"a": [1, [2, 3]], "b": [4], "c": [0, 1]}
    assert type(value["b"][0]) is int


def test_plain_copies_a_long_list_of_scalars_and_converts_numpy_in_one():
    from malcolm.core.metas import plain

    floats = [float(i) for i in range(100)]
    out = plain({"points": floats})
    assert out == {"points": floats} and out["points"] is not floats
    mixed = floats + [np.float64(2.5)]  # one numpy value: every item converted
    out = plain(mixed)
    assert out[-1] == 2.5 and type(out[-1]) is float


def test_a_float64_takes_a_python_float_as_it_is():
    """The common case (a float for a float64) is returned as it is, and the
    meta's limits still apply to it."""
    import math

    from malcolm.core import BadValueError, NumberMeta

    meta = NumberMeta("float64", display={"limitLow": 0.0, "limitHigh": 10.0})
    value = 2.5
    assert meta.validate(value) is value
    open_meta = NumberMeta("float64")
    assert open_meta.validate(math.inf) == math.inf
    assert math.isnan(open_meta.validate(math.nan))
    for bad in (11.0, -1.0, math.nan):
        try:
            meta.validate(bad)
        except BadValueError as e:
            assert "limits" in str(e)
        else:
            raise AssertionError(f"{bad} passed the limits [0, 10]")


def test_a_numpy_array_is_kept_beside_its_tuple():
    """A number array given as numpy is the tuple of its numbers, with a
    read-only copy of the array beside it: plain data and equality as a
    tuple's, numpy.asarray without a conversion."""
    given = np.linspace(0.0, 1.0, 20_001)
    value = NumberArrayMeta("float64").validate(given)
    assert isinstance(value, tuple) and type(value) is NumberArray
    assert value == tuple(given.tolist())
    out = plain(value)
    assert type(out) is list and out == plain(tuple(given.tolist()))
    assert all(type(v) is float for v in out)
    kept = np.asarray(value)
    assert kept is value.array and not kept.flags.writeable
    given[0] = 99.0  # the caller's array is not the value's
    assert value[0] == 0.0 and kept[0] == 0.0
    with pytest.raises(ValueError):
        kept[1] = 5.0
    # copies, pickles and slices are plain tuples (or the value itself)
    import copy
    import pickle

    assert copy.deepcopy(value) is value
    assert type(pickle.loads(pickle.dumps(value))) is tuple
    assert type(value[1:3]) is tuple and value[1:3] == tuple(given[1:3].tolist())
    # an integer meta keeps its own dtype; Python ints in the tuple
    ints = NumberArrayMeta("int32").validate(np.arange(2000, dtype=np.int64))
    assert type(ints) is NumberArray and np.asarray(ints).dtype == np.int32
    assert ints[:3] == (0, 1, 2) and all(type(v) is int for v in ints)
    assert plain(ints) == list(range(2000))
    # a short array is a tuple alone (quicker to make)
    assert type(NumberArrayMeta().validate(np.arange(3.0))) is tuple


def test_a_kept_array_is_checked_again_against_another_meta():
    value = NumberArrayMeta("float64").validate(np.full(1000, 300.0))
    assert type(value) is NumberArray
    assert NumberArrayMeta("float64").validate(value) is value  # nothing to redo
    with pytest.raises(BadValueError, match=r"\[0\]"):
        NumberArrayMeta("int8").validate(value)
    assert NumberArrayMeta("int16").validate(value) == (300,) * 1000
    limited = NumberArrayMeta("float64", display={"limitLow": 0, "limitHigh": 10})
    with pytest.raises(BadValueError, match=r"\[0\]"):
        limited.validate(value)


def test_the_same_numbers_again_give_the_same_value():
    """A put's readback (the numbers just validated, read back as another
    array) is the value made for the put, not a new one."""
    meta = NumberArrayMeta("float64")
    sent = np.linspace(0.0, 1.0, 5000)
    value = meta.validate(sent)
    echo = meta.validate(sent.copy())  # another array, the same numbers
    assert echo is value
    ints = meta.validate(np.arange(5000))  # other numbers: a value of their own
    assert ints is not value and ints == tuple(float(i) for i in range(5000))
    moved = sent.copy()
    moved[-1] = 2.0
    assert meta.validate(moved) is not ints and meta.validate(moved)[-1] == 2.0
    # a NaN is never the same number: made again, as a NaN
    nan = np.full(5000, np.nan)
    assert math.isnan(meta.validate(nan)[0]) and math.isnan(meta.validate(nan)[0])

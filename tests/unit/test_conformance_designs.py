"""The values the design checks write "as someone else" differ from the
design's and are valid for the attribute (malcolm.conformance.designs)."""

from __future__ import annotations

import math

import pytest

from malcolm.conformance.designs import mentions, other_value
from malcolm.core import (
    BooleanMeta,
    ChoiceMeta,
    NumberArrayMeta,
    NumberMeta,
    StringMeta,
    TableMeta,
)

TABLE = TableMeta({"a": NumberArrayMeta("int32"), "b": NumberArrayMeta("float64")})


@pytest.mark.parametrize(
    "meta, value",
    [
        (BooleanMeta(), True),
        (ChoiceMeta(("edge", "level")), "level"),
        (NumberMeta("float64"), 0.5),
        (NumberMeta("float64"), math.nan),
        (NumberMeta("float64"), 1e300),
        (NumberMeta("int32"), 0),
        (NumberMeta("int32"), 2**31 - 1),
        (NumberMeta("uint8"), 0),
        (StringMeta(), ""),
        (TABLE, TABLE.validate([{"a": 1, "b": 2.0}, {"a": 3, "b": 4.0}])),
        (TABLE, TABLE.validate({"a": [], "b": []})),
    ],
)
def test_other_value_differs_and_is_valid(meta, value) -> None:
    other = meta.validate(other_value(meta, value))
    assert repr(other) != repr(value)


def test_no_other_value_for_a_single_choice() -> None:
    assert other_value(ChoiceMeta(("only",)), "only") is None


def test_mentions_a_value_as_repr_or_str() -> None:
    assert mentions("X is fixed at 'a', but it is 'b'", "a")
    assert mentions("X is fixed at 32, but it is 31", 31)
    assert not mentions("X has drifted", 31)

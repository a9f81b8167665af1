"""Task.when_matches compares values as the attribute's meta holds them, so
arrays and tables match (issue 7 item 12)."""

import asyncio

import pytest

from malcolm.controllers.stateful import StatefulController
from malcolm.core import (
    BadValueError,
    NumberArrayMeta,
    Process,
    StringArrayMeta,
    TableMeta,
)
from malcolm.hooks import Task
from malcolm.parts import Part

from .scans import run

TABLE = TableMeta({"x": NumberArrayMeta("int32"), "name": StringArrayMeta()})


class Arrays(Part):
    def setup(self, registrar):
        self.arr = registrar.add_attribute("arr", NumberArrayMeta("float64"))
        self.table = registrar.add_attribute("table", TABLE)


async def started():
    process = Process()
    part = Arrays("arrays")
    process.add_controller(StatefulController("B", [part]))
    await process.start()
    return process, part, Task(process, "test")


def test_an_array_matches_as_a_list_or_a_tuple():
    async def scenario():
        process, part, task = await started()
        as_list = task.when_matches(("B", "arr"), [1, 2, 3], timeout=5)
        as_tuple = task.when_matches(("B", "arr"), (1.0, 2.0, 3.0), timeout=5)
        seen = task.when_matches(("B", "arr"), lambda v: len(v) == 3, timeout=5)
        part.arr.set_value([9])
        await asyncio.sleep(0)
        assert not as_list.done()
        part.arr.set_value((1, 2, 3))
        return await task.wait_all(as_list, as_tuple, seen)

    assert run(scenario) == [(1.0, 2.0, 3.0)] * 3


def test_a_table_matches_as_rows_or_columns():
    async def scenario():
        process, part, task = await started()
        rows = [{"x": 1, "name": "a"}, {"x": 2, "name": "b"}]
        columns = {"x": [1, 2], "name": ["a", "b"]}
        by_rows = task.when_matches(("B", "table"), rows, timeout=5)
        by_columns = task.when_matches(("B", "table"), columns, timeout=5)
        part.table.set_value(rows[:1])
        await asyncio.sleep(0)
        assert not by_rows.done()
        part.table.set_value(columns)
        return await task.wait_all(by_rows, by_columns)

    want = {"x": (1, 2), "name": ("a", "b")}
    assert run(scenario) == [want, want]


def test_a_value_that_cannot_fit_is_an_error_naming_the_field():
    async def scenario():
        process, part, task = await started()
        with pytest.raises(BadValueError, match=r"B\.arr: \[1\]: expected a number"):
            task.when_matches(("B", "arr"), [1, "x"])

    run(scenario)

"""A pytest plugin that runs the collected tests in another order, to find
tests that depend on what an earlier one left (a session IOC's motor, a
module's served scan): ``-p tests.system.order --test-order=reverse``, or
``--test-order=shuffle:SEED`` (modules in a seeded random order, and the
tests of each module too). Not loaded unless asked (docs/testing.md)."""

from __future__ import annotations

import random
from typing import Any

import pytest


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--test-order",
        default="",
        help="reverse, or shuffle:SEED (modules, then each module's tests)",
    )


def reorder(items: list[Any], how: str, module: Any = None) -> list[Any]:
    """``items`` in the order ``how`` names ("" keeps it); ``module(item)``
    groups them (by file unless given). ValueError for another ``how``."""
    if not how:
        return list(items)
    if how == "reverse":
        return list(reversed(items))
    kind, _, seed = how.partition(":")
    if kind != "shuffle" or not seed.isdigit():
        raise ValueError(f"--test-order {how!r}: reverse or shuffle:SEED")
    rng = random.Random(int(seed))
    groups: dict[Any, list[Any]] = {}
    for item in items:
        groups.setdefault(module(item) if module else item.path, []).append(item)
    keys = list(groups)
    rng.shuffle(keys)
    ordered = []
    for key in keys:
        group = groups[key]
        rng.shuffle(group)
        ordered += group
    return ordered


def pytest_collection_modifyitems(config: pytest.Config, items: list[Any]) -> None:
    how = config.getoption("--test-order")
    try:
        items[:] = reorder(items, how)
    except ValueError as e:
        raise pytest.UsageError(str(e)) from None


def pytest_report_header(config: pytest.Config) -> str:
    how = config.getoption("--test-order")
    return f"test order: {how}" if how else ""

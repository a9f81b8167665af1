"""tests/system/order.py: the orders it runs tests in (docs/testing.md)."""

from __future__ import annotations

import itertools
import subprocess
import sys
from pathlib import Path

import pytest

from .order import reorder

ROOT = Path(__file__).resolve().parents[2]
ITEMS = [("a", 1), ("a", 2), ("b", 1), ("b", 2), ("c", 1)]


def by_module(item):
    return item[0]


def test_reverse_and_none():
    assert reorder(ITEMS, "reverse", by_module) == list(reversed(ITEMS))
    assert reorder(ITEMS, "", by_module) == ITEMS


def test_a_shuffle_keeps_each_module_together_and_its_seed_repeats_it():
    one = reorder(ITEMS, "shuffle:7", by_module)
    assert sorted(one) == sorted(ITEMS)
    runs = [m for m, _ in itertools.groupby(m for m, _ in one)]
    assert len(runs) == len(set(runs))  # each module's tests one after another
    assert reorder(ITEMS, "shuffle:7", by_module) == one
    seen = {tuple(reorder(ITEMS, f"shuffle:{s}", by_module)) for s in range(20)}
    assert len(seen) > 1


@pytest.mark.parametrize("how", ["sideways", "shuffle:", "shuffle:x"])
def test_another_order_is_refused_naming_it(how):
    with pytest.raises(ValueError, match=f"--test-order '{how}'"):
        reorder(ITEMS, how, by_module)


def test_pytest_collects_in_the_order_asked():
    def collected(*args: str) -> list[str]:
        out = subprocess.run(
            [sys.executable, "-m", "pytest", "--co", "-q", "-p", "no:cacheprovider",
             "-p", "tests.system.order", *args, "tests/system/test_order_plugin.py"],
            cwd=ROOT, capture_output=True, text=True, timeout=60, check=False,
        )  # fmt: skip
        return [line for line in out.stdout.splitlines() if "::" in line]

    plain = collected()
    assert len(plain) > 3
    assert collected("--test-order=reverse") == list(reversed(plain))
    assert sorted(collected("--test-order=shuffle:3")) == sorted(plain)

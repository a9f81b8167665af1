"""A hook function that cannot take (task, device) is refused when its part is
added, naming the part, the phase and the function; bad phase timeouts are
refused when the controller is made."""

from __future__ import annotations

import math

import pytest

from malcolm.controllers.stateful import StatefulController
from malcolm.fsm import Stateful
from malcolm.hooks.signature import hook_problem, timeout_problem
from malcolm.parts import Part


class TooMany(Part):
    @Stateful.Reset
    async def reset(self, task, device, extra): ...


class NeedsKeyword(Part):
    @Stateful.Reset
    def reset(self, task, *, how): ...


class Fine(Part):
    @Stateful.Reset
    async def reset(self, task, device, extra=1, *, how=2): ...

    @Stateful.Disable
    def disable(self): ...


def test_too_many_arguments_refused_when_added() -> None:
    with pytest.raises(ValueError) as info:
        StatefulController("B", [TooMany("p")])
    text = str(info.value)
    assert "B: part 'p', phase Reset" in text
    assert "TooMany.reset(task, device, extra) needs 3 arguments" in text


def test_required_keyword_refused() -> None:
    with pytest.raises(ValueError, match="needs keyword argument\\(s\\) how"):
        StatefulController("B", [NeedsKeyword("p")])


def test_defaults_and_fewer_arguments_accepted() -> None:
    c = StatefulController("B", [Fine("p")])
    assert {h.part for hs in c.hooks.values() for h in hs} == {"p"}
    assert hook_problem(lambda: None) is None
    assert hook_problem(3) == "3 is not callable"


@pytest.mark.parametrize("bad", [math.nan, -1, 0, math.inf, "5", True])
def test_bad_phase_timeouts_refused(bad) -> None:
    with pytest.raises(ValueError, match="B: phase_timeout must be"):
        StatefulController("B", phase_timeout=bad)
    with pytest.raises(ValueError, match="B: phase_timeouts.Reset must be"):
        StatefulController("B", phase_timeouts={"Reset": bad})


def test_good_timeouts() -> None:
    assert timeout_problem("t", None) is None
    assert timeout_problem("t", None, allow_none=False) is not None
    StatefulController("B", phase_timeout=None, phase_timeouts={"Reset": 0.5})

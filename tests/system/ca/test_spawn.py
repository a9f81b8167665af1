"""``spawn``/``run`` of the CA tests: a scenario that fails before awaiting
what it spawned leaves no unretrieved exception for a later test."""

from __future__ import annotations

import asyncio
import gc

import pytest

from malcolm.io import DisconnectedError

from .conftest import run, spawn


def test_a_failed_scenario_takes_the_outcome_of_what_it_spawned(caplog):
    async def put_on_a_closed_channel() -> None:
        raise DisconnectedError("M2.position: CATEST:M2:VAL: closed")

    async def never_done() -> None:
        await asyncio.Event().wait()

    async def scenario() -> None:
        failed = spawn(put_on_a_closed_channel())
        spawn(never_done())
        await asyncio.sleep(0)
        await asyncio.sleep(0)
        assert failed.done()
        raise AssertionError("the scenario failed before awaiting them")

    with pytest.raises(AssertionError, match="before awaiting them"):
        run(scenario())
    gc.collect()
    dropped = [r.getMessage() for r in caplog.records if r.name == "asyncio"]
    assert dropped == []

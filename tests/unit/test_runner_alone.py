"""A phase with one async hook is awaited in place (hooks/runner.py); its
outcomes are those of the general case."""

from __future__ import annotations

import asyncio

import pytest

from malcolm.core import AbortedError, PhaseTimeoutError, WaitTimeoutError
from malcolm.hooks import Hook, PhaseError, run_phase


def phase_of(func) -> list[Hook]:
    return [Hook.make("p", "Work", func)]


TASKS = {"p": None}


def test_a_hook_that_outlives_the_timeout_is_a_phase_timeout_and_leaves_no_cancel():
    async def stuck(task, device):
        await asyncio.Event().wait()

    async def scenario():
        with pytest.raises(PhaseTimeoutError, match="Work phase timed out .* p"):
            await run_phase("Work", phase_of(stuck), TASKS, None, 0.01)
        me = asyncio.current_task()
        assert me.cancelling() == 0
        await asyncio.sleep(0)  # this task was not left cancelled

    asyncio.run(scenario())


def test_a_timeout_error_of_the_hooks_own_is_its_failure_not_the_phases_timeout():
    async def gives_up(task, device):
        raise WaitTimeoutError("the plugin did not start")

    async def scenario():
        with pytest.raises(PhaseError, match="part 'p' failed: the plugin did not"):
            await run_phase("Work", phase_of(gives_up), TASKS, None, 5)

    asyncio.run(scenario())


def test_a_hook_that_ignores_the_timeout_and_returns_is_done():
    async def stubborn(task, device):
        try:
            await asyncio.sleep(1)
        except asyncio.CancelledError:
            return "finished anyway"

    async def scenario():
        out = await run_phase("Work", phase_of(stubborn), TASKS, None, 0.01)
        assert out == {"p": "finished anyway"}
        assert asyncio.current_task().cancelling() == 0

    asyncio.run(scenario())


def test_cancelling_the_phase_cancels_the_hook():
    cancelled = []

    async def waits(task, device):
        try:
            await asyncio.Event().wait()
        except asyncio.CancelledError:
            cancelled.append(True)
            raise

    async def scenario():
        phase = asyncio.ensure_future(
            run_phase("Work", phase_of(waits), TASKS, None, 5)
        )
        await asyncio.sleep(0.01)
        phase.cancel()
        with pytest.raises(asyncio.CancelledError):
            await phase
        assert cancelled == [True]

    asyncio.run(scenario())


def test_a_hook_cancelled_from_inside_is_a_phase_error():
    async def loses_its_future(task, device):
        fut = asyncio.get_running_loop().create_future()
        fut.cancel()
        await fut

    async def scenario():
        with pytest.raises(PhaseError) as caught:
            await run_phase("Work", phase_of(loses_its_future), TASKS, None, 5)
        assert isinstance(caught.value.cause, AbortedError)

    asyncio.run(scenario())

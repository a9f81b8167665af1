"""Seeded defect: the phase runner returns as soon as the first part's hook
returns, leaving the others running (seam: malcolm.hooks.runner.run_phase)."""

import asyncio

import malcolm.hooks.runner
from tests.seeded import replace_everywhere

original = malcolm.hooks.runner.run_phase


async def run_phase(phase, hooks, tasks, device, timeout=None):
    if len(hooks) < 2:
        return await original(phase, hooks, tasks, device, timeout)
    first = asyncio.ensure_future(original(phase, hooks[:1], tasks, device, timeout))
    rest = asyncio.ensure_future(original(phase, hooks[1:], tasks, device, timeout))
    rest.add_done_callback(lambda f: f.cancelled() or f.exception())
    return await first


replace_everywhere(original, run_phase)

"""Seeded defect: the controller moves out of Seeking without running the
transition's Seek phase (seam: malcolm.hooks.runner.run_phase, which the
controller calls for each phase of a transition)."""

import malcolm.hooks.runner
from tests.seeded import replace_everywhere

original = malcolm.hooks.runner.run_phase


async def run_phase(phase, hooks, tasks, device, timeout=None):
    if phase == "Seek":
        return {}
    return await original(phase, hooks, tasks, device, timeout)


replace_everywhere(original, run_phase)

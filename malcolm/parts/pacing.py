"""Pace simulated work against fixed deadlines, so a scan's overhead does not
grow with its length.

Sleeping a point's duration after doing its work makes every point last the
duration plus the work plus the timer's overshoot, and those add up over a
scan (0.5 ms a point on the demo scan). A :class:`Deadlines` instead waits
for the run's start plus the sum of the durations so far, on the loop's
clock, so a point that ends late is made up by the next one waiting less: a
run lasts its total duration plus the lateness of its last point, whatever
its length. The simulated detector, the demo scan's motor moves and the
simulated position plugin pace their points this way.
"""

from __future__ import annotations

import asyncio

__all__ = ["Deadlines"]


def _now() -> float:
    return asyncio.get_running_loop().time()


_sleep = asyncio.sleep


class Deadlines:
    """The deadlines of one run: it starts now (``loop.time()``), and each
    point ends its duration after the previous deadline, not after the
    previous point really ended."""

    def __init__(self) -> None:
        #: the latest deadline, on the loop's clock: the start at first
        self.deadline = _now()

    async def wait(self, seconds: float) -> None:
        """Wait until ``seconds`` after the previous deadline. When behind
        time it only yields to the loop once, so other blocks stay live."""
        self.deadline += seconds
        await _sleep(max(0.0, self.deadline - _now()))

"""The scan's step maths: which steps a run does, and where a pause lands.

A run does the steps of the innermost dimensions whose axes are all in
``axesToMove``, cut short at the next breakpoint. ``pause(lastGoodStep)``
follows the reference (pymalcolm's RunnableController.pause): a negative
(or no) step means the current one, a step at or past the end the last one
(so a pause of a Finished scan lands Armed on its last step, as the
reference's does), and a pause that leaves a run waiting (Paused) goes back
one step if it would land on the end of the run, so that resume always has
a step to do.
"""

from __future__ import annotations

import asyncio
import copy
import sys
import threading
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from itertools import accumulate
from typing import TYPE_CHECKING, Any

from malcolm.core import BadValueError

if TYPE_CHECKING:  # malcolm.scan (numpy) is imported when a scan is planned
    from malcolm.scan import ScanPoints


class PointsCache:
    """The points of the last few generators given as plain data, so that
    validate() then configure() (or a configure repeated, or the children a
    manager configures with the same generator) computes a scan's points
    once. A generator matches an entry if it is equal to the copy the entry
    keeps (so a caller changing its dict later changes nothing here). Safe to
    use from several threads: points are computed outside its lock."""

    def __init__(self, size: int = 4) -> None:
        self.size = size
        self._items: list[tuple[Any, ScanPoints]] = []
        self._lock = threading.Lock()

    def find(self, generator: Any) -> ScanPoints | None:
        """The points of an equal generator seen before, or None."""
        if not isinstance(generator, Mapping):
            return None
        with self._lock:
            for i, (seen, points) in enumerate(self._items):
                try:
                    equal = bool(seen == generator)
                except (ValueError, TypeError):  # arrays compare element-wise
                    equal = False
                if equal:
                    if i:
                        self._items.insert(0, self._items.pop(i))
                    return points
        return None

    def known(self, generator: Any) -> bool:
        """Whether the points of ``generator`` need no computing (they are
        ScanPoints, or an equal generator's are kept)."""
        points = sys.modules.get("malcolm.scan.points")  # none made if not loaded
        if points is not None and isinstance(generator, points.ScanPoints):
            return True
        return self.find(generator) is not None

    def points(self, generator: Any) -> ScanPoints:
        """The points of ``generator`` (GeneratorError if it is not a scan)."""
        from malcolm.scan import ScanPoints, scan_points

        if isinstance(generator, ScanPoints):
            return generator
        found = self.find(generator)
        if found is None:
            found = scan_points(generator)
            if isinstance(generator, Mapping):
                kept = copy.deepcopy(generator)
                with self._lock:
                    self._items.insert(0, (kept, found))
                    del self._items[self.size :]
        return found


#: shared by every runnable controller of the process
POINTS = PointsCache()


@dataclass(frozen=True)
class ScanPlan:
    """A checked scan: its points and how it is cut into runs."""

    points: ScanPoints
    steps_per_run: int = 1
    breakpoint_ends: tuple[int, ...] = field(default_factory=tuple)

    @property
    def total(self) -> int:
        return self.points.size

    def next_configured(self, completed: int) -> int:
        """Where a run that starts at step ``completed`` stops."""
        total = self.total
        spr = max(1, self.steps_per_run)
        end = min(total, (completed // spr + 1) * spr)
        for b in self.breakpoint_ends:
            if b > completed:
                end = min(end, b)
                break
        return end


def plan_scan(
    mri: str, params: Mapping[str, Any], simultaneous_axes: Sequence[str]
) -> ScanPlan:
    """Check configure parameters: BadValueError naming what is wrong."""
    from malcolm.scan.errors import GeneratorError

    try:
        points = POINTS.points(params["generator"])
        axes = params.get("axesToMove")
        if axes is None:
            axes = list(simultaneous_axes) or None
        spr = points.steps_per_run(list(axes) if axes is not None else None)
    except (GeneratorError, ValueError) as e:
        raise BadValueError(f"{mri}.configure: {e}") from None
    breakpoints = [int(b) for b in params.get("breakpoints") or ()]
    if breakpoints and sum(breakpoints) != points.size:
        raise BadValueError(
            f"{mri}.configure.breakpoints: they add up to {sum(breakpoints)}"
            f" but the scan has {points.size} points"
        )
    if any(b <= 0 for b in breakpoints):
        raise BadValueError(f"{mri}.configure.breakpoints: must be positive")
    return ScanPlan(points, spr, tuple(accumulate(breakpoints)))


async def plan_scan_off_loop(
    mri: str, params: Mapping[str, Any], simultaneous_axes: Sequence[str]
) -> ScanPlan:
    """:func:`plan_scan` in a worker thread, so that the loop (and every other
    block) stays live while a big scan's points are computed; at once if
    they are known already. The plan is plain data: the caller applies it on
    the loop. Cancelling the wait leaves the thread to finish on its own."""
    axes = list(simultaneous_axes)
    if POINTS.known(params.get("generator")):
        return plan_scan(mri, params, axes)
    return await asyncio.to_thread(plan_scan, mri, dict(params), axes)


def pause_step(
    requested: int | None,
    completed: int,
    configured: int,
    total: int,
    lands_paused: bool,
) -> int:
    """The step ``pause(lastGoodStep=requested)`` goes back to (the module's
    rules); ``lands_paused``: a run is waiting (the block ends Paused)."""
    step = completed if requested is None or requested < 0 else int(requested)
    # at or past the end (the current step of a Finished scan is the end):
    # the last step
    step = min(step, total - 1)
    if lands_paused and step == configured:
        step -= 1
    return max(0, step)

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
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from itertools import accumulate
from typing import TYPE_CHECKING, Any

from malcolm.core import BadValueError

if TYPE_CHECKING:  # malcolm.scan (numpy) is imported when a scan is planned
    from malcolm.scan import ScanPoints


def is_scan_points(generator: Any) -> bool:
    """Whether ``generator`` is ScanPoints already (nothing to compute);
    never loads malcolm.scan (numpy) to find out."""
    points = sys.modules.get("malcolm.scan.points")
    return points is not None and isinstance(generator, points.ScanPoints)


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
    from malcolm.scan import scan_points
    from malcolm.scan.errors import GeneratorError
    from malcolm.scan.planned import planned_points

    try:
        generator = params["generator"]
        # the very object the operation in progress planned: its points
        planned = planned_points(generator)
        points = planned.copy() if planned is not None else scan_points(generator)
        axes = params.get("axesToMove")
        if axes is None:
            # the axes the block can move together that this scan has (as
            # pymalcolm: a line in x on an x/y controller moves x)
            axes = [a for a in simultaneous_axes if a in points.axes] or None
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


def plans_on_loop(params: Mapping[str, Any]) -> bool:
    """Whether planning ``params`` is cheap enough to do on the loop: the
    generator is ScanPoints already or the very object the operation in
    progress planned (`malcolm.scan.planned`), or the scan is cheap to build
    (`malcolm.scan.cheap_to_build`, breakpoints counted as data) and the
    modules that build it are loaded (the first scan imports numpy and
    them, in the worker thread)."""
    generator = params.get("generator")
    if is_scan_points(generator):
        return True
    if "malcolm.scan.load" not in sys.modules:
        return False  # nothing planned yet
    from malcolm.scan.planned import planned_points

    if planned_points(generator) is not None:
        return True
    from malcolm.scan.cost import CHEAP_BUILD_COST, DATA_ITEM_COST, build_cost

    try:
        breakpoints = len(params.get("breakpoints") or ())
    except (TypeError, ValueError):
        return False  # not a list: as plan_scan would take it, off the loop
    extra = breakpoints * DATA_ITEM_COST
    return build_cost(generator, CHEAP_BUILD_COST - extra) + extra <= CHEAP_BUILD_COST


async def plan_scan_off_loop(
    mri: str, params: Mapping[str, Any], simultaneous_axes: Sequence[str]
) -> ScanPlan:
    """:func:`plan_scan`, in a worker thread where building the scan is
    costly, so that the loop (and every other block) stays live while a big
    scan's points are computed; on the loop where it is cheap
    (:func:`plans_on_loop`: well under a millisecond, less than the hop to
    a thread and back). The plan is plain data: the caller applies it on
    the loop. Cancelling the wait leaves the thread to finish on its own.

    A scan is built once: ``malcolm.scan.scan_points`` keeps the last few
    it built by content, so configure() after validate() of the same scan,
    and the children a manager configures with its generator, take the
    points already built (in the thread, for a costly scan: finding them
    means reading the whole generator, which may be big)."""
    axes = list(simultaneous_axes)
    if plans_on_loop(params):
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

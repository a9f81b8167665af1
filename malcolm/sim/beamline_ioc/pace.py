"""The simulation's pace: its shortest point, and status records posted at
a bounded rate, as a controller's status poll.

:data:`MIN_PERIOD` is the shortest frame period (and trajectory point) the
simulated IOC sustains with malcolm following it: measured with
``benchmarks.beamline_timeline --shape spiral`` (10,000 points back to back,
2-core machine), the IOC keeps its schedule at 0.05 ms a point and falls
behind at 0.02 ms (about 0.054 ms a point flat out); 0.1 ms leaves room for
a loaded machine. The DetectorManager's validate raises shorter durations
to it (its ``MIN_EXPOSURE``, docs/devices.md). A late trajectory or
acquisition does its due points at once, yielding to the IOC's other work
every :data:`LATE_SLICE`.

A real motion controller's progress (``PointsScanned_RBV``) and a detector's
counters reach Channel Access at the rate its driver polls or publishes
them, not once per point or frame. :class:`Throttled` wraps a softioc input
record the same way: the IOC's code reads and sets the value as often as it
likes (``get`` gives the value set last), and the record is posted at most
every :data:`STATUS_PERIOD`:

- a change after a quiet period is posted at once (so changes slower than
  the period, a frame every 10 ms, are each posted as they happen);
- later changes within the period are posted once, with the latest value,
  at the period's end (so the last value always reaches the clients, at
  most one period late);
- :meth:`Throttled.flush` posts the value now: the IOC flushes before a
  busy put completes (``Acquire``, ``Capture``, ``Running``,
  ``ExecuteProfile``), so a client sees the final counts when its put
  returns (one IOC's posts reach a client in order).
"""

from __future__ import annotations

import asyncio
import math
from typing import Any

__all__ = ["LATE_SLICE", "MIN_PERIOD", "STATUS_PERIOD", "Schedule", "Throttled"]

#: seconds between two posts of a status record (a 200 Hz status poll)
STATUS_PERIOD = 0.005
#: the shortest frame period / point time (s) the simulation sustains
MIN_PERIOD = 0.0001
#: seconds a late trajectory or acquisition works through due points
#: before it yields to the IOC's other work
LATE_SLICE = 0.002


class Schedule:
    """Waits for points on an absolute schedule (on the running loop): a
    point due later is slept for; points already due are done at once, with
    a yield to the IOC's other work every :data:`LATE_SLICE`, so lateness
    is caught up, never accumulated."""

    def __init__(self) -> None:
        self.loop = asyncio.get_running_loop()
        self.start = self._yielded = self.loop.time()

    async def until(self, deadline: float) -> None:
        """Return at ``deadline`` (loop time) or, if it has passed, now."""
        now = self.loop.time()
        if deadline > now:
            await asyncio.sleep(deadline - now)
            self._yielded = self.loop.time()
        elif now - self._yielded > LATE_SLICE:  # catching up: let others run
            await asyncio.sleep(0)
            self._yielded = self.loop.time()


class Throttled:
    """A softioc input record posted at most every ``period`` seconds."""

    def __init__(self, record: Any, period: float = STATUS_PERIOD) -> None:
        self.record = record
        self.period = period
        self._value = record.get()
        self._posted = self._value
        self._posted_at = -math.inf
        self._timer: asyncio.TimerHandle | None = None

    def get(self) -> Any:
        """The value set last (posted or not)."""
        return self._value

    def set(self, value: Any) -> None:
        """Take ``value``; post it now if the last post is a period old, else
        at the end of the period (with whatever value is latest then)."""
        self._value = value
        if self._timer is not None:
            return  # a post is due: it takes the latest value
        try:
            loop = asyncio.get_running_loop()
        except RuntimeError:  # not on the IOC's loop (building): post now
            self._post(0.0)
            return
        now = loop.time()
        wait = self._posted_at + self.period - now
        if wait <= 0:
            self._post(now)
        else:
            self._timer = loop.call_later(wait, self._due, loop)

    def _due(self, loop: asyncio.AbstractEventLoop) -> None:
        self._timer = None
        self._post(loop.time())

    def _post(self, now: float) -> None:
        self._posted_at = now
        self._posted = self._value
        self.record.set(self._value)

    def flush(self, **fields: Any) -> None:
        """Post the latest value now if it was not posted (always, with
        ``fields``: ``severity``, ``alarm``)."""
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        elif self._posted == self._value and not fields:
            return
        try:
            now = asyncio.get_running_loop().time()
        except RuntimeError:
            now = 0.0
        self._posted_at = now
        self._posted = self._value
        self.record.set(self._value, **fields)

"""PCOMP in closed form: pulses as a counter's position passes thresholds.

Supported wiring: ``PCOMPn.INP`` is a COUNTER counting the rising edges of a
CLOCK, so the position only changes on that clock's edges: after the J-th
edge it is ``a + s*J``.  From the enable, pulse k (k = 0.. PULSES-1, PULSES 0
= no limit) rises on the first edge where the position has passed
``START + k*STEP`` in DIR (``Negative``: downwards; thresholds already
passed at enable are skipped; ``Relative``: START from the position at
enable) and falls on the first later edge where it has passed the threshold
plus WIDTH.  ACTIVE is high from the enable until the last pulse has
fallen.  Everything is a formula of the edge number, so any interval and
any number of sample ticks cost a few numpy operations.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .clocks import ClockModel, CounterModel


def _ceil_div(x: np.ndarray | int, y: int) -> np.ndarray | int:
    return -((-x) // y)


@dataclass
class PcompModel:
    """One PCOMP instance while enabled (``clock`` None: makes no pulses)."""

    name: str
    clock: ClockModel | None = None
    a: int = 0
    s: int = 0
    base: int = 0
    t0: int = 0
    step: int = 0
    width: int = 0
    pulses: int = 0
    dir: int = 1
    enabled: bool = False

    def configure(
        self,
        counter: CounterModel | None,
        t: int,
        start: int,
        step: int,
        width: int,
        pulses: int,
        negative: bool,
        relative: bool,
        enabling: bool,
    ) -> None:
        """Take the parameters at tick ``t`` (``enabling``: the enable edge)."""
        if (
            counter is None
            or counter.trig is None
            or not counter.enabled
            or counter.edge != "Rising"
        ):
            self.clock = None
            return
        self.clock = counter.trig
        self.s = counter.step
        self.a = counter.value_at(t) - self.s * self.clock.rises_upto(t)
        self.dir = -1 if negative else 1
        self.step, self.width, self.pulses = abs(step), abs(width), pulses
        if enabling:
            position = counter.value_at(t)
            self.t0 = start + (position if relative else 0)
            self.base = int(self._raw(self.clock.rises_upto(t), 0))

    def _moving(self) -> bool:
        # a counter whose clock is not running yet holds still: no pulses,
        # ACTIVE stays high until the clock starts and the pulses are made
        return (
            self.clock is not None
            and self.clock.running()
            and self.enabled
            and self.dir * self.s > 0
        )

    def _raw(self, j, offset: int):
        """Thresholds (plus ``offset``) passed by the position at edge ``j``."""
        dist = self.dir * (self.a + self.s * np.asarray(j, dtype=np.int64) - self.t0)
        dist = dist - offset
        if self.step == 0:
            return (dist >= 0).astype(np.int64)
        return np.where(dist >= 0, dist // self.step + 1, 0)

    def _passed(self, j, offset: int):
        """Pulses whose threshold (plus ``offset``) was passed since enable."""
        n = np.maximum(self._raw(j, offset) - self.base, 0)
        return np.minimum(n, self.pulses) if self.pulses else n

    def _counts(self, j):
        """(risen, fallen) pulse counts at edge number(s) ``j``."""
        if not self._moving():
            zero = np.zeros_like(np.asarray(j, dtype=np.int64))
            return zero, zero
        j = np.asarray(j, dtype=np.int64)
        risen = self._passed(j, 0)
        fallen = np.minimum(self._passed(j, self.width), self._passed(j - 1, 0))
        return risen, fallen

    def _edge(self, t) -> np.ndarray:
        assert self.clock is not None
        return self.clock.rises_upto_array(np.atleast_1d(np.asarray(t, np.int64)))

    # -- OUT ---------------------------------------------------------------
    def out_at_array(self, ticks: np.ndarray) -> np.ndarray:
        if not self._moving():
            return np.zeros(len(ticks), dtype=np.int64)
        risen, fallen = self._counts(self._edge(ticks))
        return (risen > fallen).astype(np.int64)

    def out_at(self, t: int) -> int:
        return int(self.out_at_array(np.array([t]))[0])

    def produced(self, t: int) -> int:
        """Pulses risen by tick ``t``."""
        if not self._moving():
            return 0
        return int(self._counts(self._edge(t))[0][0])

    def toggles(self, a: int, b: int) -> int:
        """Rises plus falls of OUT in (a, b]."""
        if not self._moving():
            return 0
        r, f = self._counts(self._edge(np.array([a, b])))
        return int(r[1] - r[0] + f[1] - f[0])

    def rises_between(self, a: int, b: int, limit: int) -> np.ndarray:
        """Ticks where OUT rises in (a, b], at most ``limit`` of them."""
        if not self._moving():
            return np.zeros(0, dtype=np.int64)
        assert self.clock is not None
        r = self._counts(self._edge(np.array([a, b])))[0]
        k = np.arange(int(r[0]), min(int(r[1]), int(r[0]) + limit), dtype=np.int64)
        # the first edge at which pulse k's threshold is passed
        need = (self.base + k) * self.step + self.dir * (self.t0 - self.a)
        j = _ceil_div(need, self.dir * self.s)
        return self.clock.te + self.clock.period * (j - 1)  # type: ignore[operator]

    # -- ACTIVE ------------------------------------------------------------
    def end_tick(self) -> int | None:
        """The tick ACTIVE falls (the last pulse fell), None if it never does."""
        if not self._moving() or not self.pulses:
            return None
        assert self.clock is not None
        last = self.pulses - 1
        need_rise = (self.base + last) * self.step + self.dir * (self.t0 - self.a)
        rise = int(_ceil_div(need_rise, self.dir * self.s))
        fall = max(int(_ceil_div(need_rise + self.width, self.dir * self.s)), rise + 1)
        return self.clock.te + self.clock.period * (fall - 1)  # type: ignore[operator]

    def active_at(self, t: int) -> int:
        if not self.enabled:
            return 0
        end = self.end_tick()
        return int(end is None or t < end)


class PcompOut:
    """``PCOMPn.OUT`` as a bit source."""

    def __init__(self, model: PcompModel) -> None:
        self.model = model

    def out_at(self, t: int) -> int:
        return self.model.out_at(t)

    def out_at_array(self, ticks: np.ndarray) -> np.ndarray:
        return self.model.out_at_array(ticks)

    def rises_between(self, a: int, b: int, limit: int) -> np.ndarray:
        return self.model.rises_between(a, b, limit)

    def end_tick(self) -> int | None:
        return None


class PcompActive:
    """``PCOMPn.ACTIVE`` as a bit source: high until the last pulse fell."""

    def __init__(self, model: PcompModel) -> None:
        self.model = model

    def out_at(self, t: int) -> int:
        return self.model.active_at(t)

    def out_at_array(self, ticks: np.ndarray) -> np.ndarray:
        if not self.model.enabled:
            return np.zeros(len(ticks), dtype=np.int64)
        end = self.model.end_tick()
        if end is None:
            return np.ones(len(ticks), dtype=np.int64)
        return (ticks < end).astype(np.int64)

    def rises_between(self, a: int, b: int, limit: int) -> np.ndarray:
        return np.zeros(0, dtype=np.int64)

    def end_tick(self) -> int | None:
        return self.model.end_tick() if self.model.enabled else None

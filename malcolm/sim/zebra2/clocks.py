"""CLOCK and COUNTER in closed form (125 MHz ticks).

A CLOCK enabled at tick ``te`` rises at ``te + k*PERIOD`` (k >= 0) and falls
``WIDTH`` later (half the period if WIDTH is 0 or not less than PERIOD).  A
COUNTER adds ``STEP`` on every edge of its TRIG (a clock output) that its
TRIG_EDGE selects (Rising, Falling, Either) while enabled, from ``START``
when enabled.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class ClockModel:
    """One CLOCK instance."""

    name: str
    te: int | None = None
    period: int = 0
    width: int = 0

    def running(self) -> bool:
        return self.te is not None and self.period > 0

    def rises_upto(self, t: int) -> int:
        """Rising edges at ticks <= t."""
        if not self.running() or t < self.te:  # type: ignore[operator]
            return 0
        return (t - self.te) // self.period + 1  # type: ignore[operator]

    def falls_upto(self, t: int) -> int:
        if not self.running() or t < self.te + self.width:  # type: ignore[operator]
            return 0
        return (t - self.te - self.width) // self.period + 1  # type: ignore[operator]

    def out_at(self, t: int) -> int:
        if not self.running() or t < self.te:  # type: ignore[operator]
            return 0
        return int((t - self.te) % self.period < self.width)  # type: ignore[operator]

    def rises_upto_array(self, ticks: np.ndarray) -> np.ndarray:
        if not self.running():
            return np.zeros(len(ticks), dtype=np.int64)
        n = (ticks - self.te) // self.period + 1
        return np.where(ticks >= self.te, n, 0)

    def out_at_array(self, ticks: np.ndarray) -> np.ndarray:
        if not self.running():
            return np.zeros(len(ticks), dtype=np.int64)
        phase = (ticks - self.te) % self.period
        return ((ticks >= self.te) & (phase < self.width)).astype(np.int64)

    def end_tick(self) -> int | None:
        """A clock never stops by itself."""
        return None

    def rises_between(self, a: int, b: int, limit: int) -> np.ndarray:
        """Ticks of the rising edges in (a, b], at most ``limit`` of them."""
        if not self.running() or b <= a:
            return np.zeros(0, dtype=np.int64)
        k0 = self.rises_upto(a)
        k1 = min(self.rises_upto(b), k0 + limit)
        return self.te + self.period * np.arange(k0, k1, dtype=np.int64)

    def falls_between(self, a: int, b: int, limit: int) -> np.ndarray:
        """Ticks of the falling edges in (a, b], at most ``limit`` of them."""
        if not self.running() or b <= a:
            return np.zeros(0, dtype=np.int64)
        k0 = self.falls_upto(a)
        k1 = min(self.falls_upto(b), k0 + limit)
        first = self.te + self.width  # type: ignore[operator]
        return first + self.period * np.arange(k0, k1, dtype=np.int64)

    def edges_between(self, a: int, b: int, limit: int, edge: str) -> np.ndarray:
        """Ticks of the ``Rising``/``Falling``/``Either`` edges in (a, b]."""
        if edge == "Rising":
            return self.rises_between(a, b, limit)
        if edge == "Falling":
            return self.falls_between(a, b, limit)
        both = np.concatenate(
            [self.rises_between(a, b, limit), self.falls_between(a, b, limit)]
        )
        return np.sort(both)[:limit]

    def edges_upto(self, t: int, edge: str) -> int:
        rises = self.rises_upto(t) if edge != "Falling" else 0
        return rises + (self.falls_upto(t) if edge != "Rising" else 0)

    def edges_upto_array(self, ticks: np.ndarray, edge: str) -> np.ndarray:
        out = np.zeros(len(ticks), dtype=np.int64)
        if not self.running():
            return out
        if edge != "Falling":
            out += self.rises_upto_array(ticks)
        if edge != "Rising":
            n = (ticks - self.te - self.width) // self.period + 1
            out += np.where(ticks >= self.te + self.width, n, 0)  # type: ignore[operator]
        return out


@dataclass
class CounterModel:
    """One COUNTER instance: its value was ``value`` at tick ``t``."""

    name: str
    enabled: bool = False
    trig: ClockModel | None = None
    edge: str = "Rising"  # TRIG_EDGE
    step: int = 0
    value: int = 0
    t: int = 0

    def value_at(self, t: int) -> int:
        if not self.enabled or self.trig is None:
            return self.value
        return self.value + self.step * (
            self.trig.edges_upto(t, self.edge) - self.trig.edges_upto(self.t, self.edge)
        )

    def value_at_array(self, ticks: np.ndarray) -> np.ndarray:
        if not self.enabled or self.trig is None:
            return np.full(len(ticks), self.value, dtype=np.int64)
        edges = self.trig.edges_upto_array(ticks, self.edge)
        edges -= self.trig.edges_upto(self.t, self.edge)
        return self.value + self.step * edges


def wrap32(value: int) -> int:
    value &= 0xFFFFFFFF
    return value - (1 << 32) if value >= 1 << 31 else value

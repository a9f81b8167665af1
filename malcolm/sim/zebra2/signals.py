"""Closed-form models of the blocks that move: CLOCK, COUNTER, BITS, PCOMP.

Time is in 125 MHz ticks.  A CLOCK enabled at tick ``te`` rises at
``te + k*PERIOD`` (k >= 0) and falls ``WIDTH`` later (half the period if
WIDTH is 0 or not less than PERIOD).  A COUNTER adds ``STEP`` on every rising
edge of its TRIG (a clock output) while enabled, from ``START`` when enabled.
BITS outputs follow A..D.  A PCOMP shows ACTIVE and ``WAIT_RISING`` while
enabled.  Mux inputs wired to anything else are taken as constant at their
current value.  Because the model is closed-form, any interval is advanced
in one step, and the values at many sample ticks are computed at once with
numpy (what lets a capture run at MHz rates).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .box import Box
from .fields import BitOutField, EnumField, NumberField, PosOutField, TimeField


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

    def rises_between(self, a: int, b: int, limit: int) -> np.ndarray:
        """Ticks of the rising edges in (a, b], at most ``limit`` of them."""
        if not self.running() or b <= a:
            return np.zeros(0, dtype=np.int64)
        k0 = self.rises_upto(a)
        k1 = min(self.rises_upto(b), k0 + limit)
        return self.te + self.period * np.arange(k0, k1, dtype=np.int64)


@dataclass
class CounterModel:
    """One COUNTER instance: its value was ``value`` at tick ``t``."""

    name: str
    enabled: bool = False
    trig: ClockModel | None = None
    step: int = 0
    value: int = 0
    t: int = 0

    def value_at(self, t: int) -> int:
        if not self.enabled or self.trig is None:
            return self.value
        return self.value + self.step * (
            self.trig.rises_upto(t) - self.trig.rises_upto(self.t)
        )

    def value_at_array(self, ticks: np.ndarray) -> np.ndarray:
        if not self.enabled or self.trig is None:
            return np.full(len(ticks), self.value, dtype=np.int64)
        edges = self.trig.rises_upto_array(ticks) - self.trig.rises_upto(self.t)
        return self.value + self.step * edges


def wrap32(value: int) -> int:
    value &= 0xFFFFFFFF
    return value - (1 << 32) if value >= 1 << 31 else value


class Signals:
    """The moving parts of a box, advanced lazily to the time asked."""

    def __init__(self, box: Box) -> None:
        self.box = box
        self.t = 0
        self.clocks = {
            inst.name: ClockModel(inst.name)
            for inst in box.instances.get("CLOCK", [])
            if box.layout.name == "tier2"
        }
        self.counters = {
            inst.name: CounterModel(inst.name)
            for inst in box.instances.get("COUNTER", [])
            if box.layout.name == "tier2"
        }

    # -- wiring --------------------------------------------------------------
    def source(self, mux: str) -> ClockModel | int:
        """What a bit_mux selects: a running clock, or a constant bit."""
        if mux == "ONE":
            return 1
        if mux == "ZERO":
            return 0
        clock = mux.rsplit(".", 1)[0]
        if mux.endswith(".OUT") and clock in self.clocks:
            return self.clocks[clock]
        state = self.box.by_key.get(mux)
        if state and isinstance(state[0], BitOutField):
            return state[0].value
        return 0

    def bit_high(self, mux: str, t: int) -> bool:
        src = self.source(mux)
        return bool(src.out_at(t) if isinstance(src, ClockModel) else src)

    def _mux(self, block: str, field: str) -> str:
        state = self.box.field(f"{block}.{field}")
        assert isinstance(state, EnumField)
        return state.value

    def rewire(self, t: int) -> None:
        """Apply the current parameters at tick ``t`` (after a write)."""
        self.advance(t)
        for name, clock in self.clocks.items():
            period = self._ticks(name, "PERIOD")
            width = self._ticks(name, "WIDTH")
            if not 0 < width < period:
                width = period // 2
            on = self.bit_high(self._mux(name, "ENABLE"), t)
            if not on:
                clock.te = None
            elif clock.te is None or (period, width) != (clock.period, clock.width):
                clock.te = t
            clock.period, clock.width = period, width
        for name, counter in self.counters.items():
            counter.value = counter.value_at(t)
            counter.t = t
            on = self.bit_high(self._mux(name, "ENABLE"), t)
            if on and not counter.enabled:
                counter.value = self._number(name, "START")
            counter.enabled = on
            trig = self.source(self._mux(name, "TRIG"))
            counter.trig = trig if isinstance(trig, ClockModel) else None
            counter.step = self._number(name, "STEP")
        for inst in self.box.instances.get("BITS", []):
            for letter in "ABCD":
                out = inst.fields.get(f"OUT{letter}")
                bit = inst.fields.get(letter)
                if isinstance(out, BitOutField) and isinstance(bit, NumberField):
                    out.set_live(bit.value)
        for inst in self.box.instances.get("PCOMP", []):
            if self.box.layout.name != "tier2":
                break
            on = self.bit_high(self._mux(inst.name, "ENABLE"), t)
            active, state = inst.fields["ACTIVE"], inst.fields["STATE"]
            assert isinstance(active, BitOutField) and isinstance(state, EnumField)
            active.set_live(int(on))
            state.set_live("WAIT_RISING" if on else "WAIT_ENABLE")
        self._publish(t, self.t)

    def _ticks(self, block: str, field: str) -> int:
        state = self.box.field(f"{block}.{field}")
        assert isinstance(state, TimeField)
        return state.ticks

    def _number(self, block: str, field: str) -> int:
        state = self.box.field(f"{block}.{field}")
        assert isinstance(state, NumberField)
        return state.value

    # -- time ------------------------------------------------------------
    def advance(self, t: int) -> None:
        """Bring every live value to tick ``t``."""
        if t <= self.t:
            return
        before, self.t = self.t, t
        self._publish(t, before)

    def _publish(self, t: int, before: int) -> None:
        for name, clock in self.clocks.items():
            out = self.box.field(f"{name}.OUT")
            assert isinstance(out, BitOutField)
            toggled = (clock.rises_upto(t) - clock.rises_upto(before)) + (
                clock.falls_upto(t) - clock.falls_upto(before)
            )
            out.value = clock.out_at(t)
            if toggled:
                self.box.touch(out.key)
        for name, counter in self.counters.items():
            out = self.box.field(f"{name}.OUT")
            assert isinstance(out, PosOutField)
            out.set_live(wrap32(counter.value_at(t)))

"""The blocks that move (tier 2): CLOCK, COUNTER, PCOMP, BITS.

CLOCK and COUNTER are modelled in `clocks`, PCOMP in `pcomp`; BITS outputs
follow A..D.  A bit_mux selects a *source*: a constant bit, or something
with edges (a clock output, a PCOMP's OUT or ACTIVE) that answers
``out_at(t)``, ``out_at_array(ticks)``, ``rises_between(a, b, limit)`` and
``end_tick()``.  Inputs wired to anything else are taken as constant at
their current value.  Because every model is closed-form, any interval is
advanced in one step, and values at many sample ticks are computed at once
with numpy (what lets a capture run at MHz rates).
"""

from __future__ import annotations

from .box import Box
from .clocks import ClockModel, CounterModel, wrap32
from .fields import BitOutField, EnumField, NumberField, PosOutField, TimeField
from .pcomp import PcompActive, PcompModel, PcompOut

Source = ClockModel | PcompOut | PcompActive


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
        self.pcomps = {
            inst.name: PcompModel(inst.name)
            for inst in box.instances.get("PCOMP", [])
            if box.layout.name == "tier2"
        }

    # -- wiring --------------------------------------------------------------
    def source(self, mux: str) -> Source | int:
        """What a bit_mux selects: something with edges, or a constant bit."""
        if mux == "ONE":
            return 1
        if mux == "ZERO":
            return 0
        block, _, out = mux.rpartition(".")
        if out == "OUT" and block in self.clocks:
            return self.clocks[block]
        if block in self.pcomps and out in ("OUT", "ACTIVE"):
            model = self.pcomps[block]
            return PcompOut(model) if out == "OUT" else PcompActive(model)
        state = self.box.by_key.get(mux)
        if state and isinstance(state[0], BitOutField):
            return state[0].value
        return 0

    def bit_high(self, mux: str, t: int) -> bool:
        src = self.source(mux)
        return bool(src if isinstance(src, int) else src.out_at(t))

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
            counter.edge = self._mux(name, "TRIG_EDGE")
            counter.step = self._number(name, "STEP")
        for inst in self.box.instances.get("BITS", []):
            for letter in "ABCD":
                out = inst.fields.get(f"OUT{letter}")
                bit = inst.fields.get(letter)
                if isinstance(out, BitOutField) and isinstance(bit, NumberField):
                    out.set_live(bit.value)
        for name, pcomp in self.pcomps.items():
            on = self.bit_high(self._mux(name, "ENABLE"), t)
            inp = self._mux(name, "INP")
            counter = self.counters.get(inp[:-4]) if inp.endswith(".OUT") else None
            pcomp.configure(
                counter,
                t,
                start=self._number(name, "START"),
                step=self._number(name, "STEP"),
                width=self._number(name, "WIDTH"),
                pulses=self._number(name, "PULSES"),
                negative=self._mux(name, "DIR") == "Negative",
                relative=self._mux(name, "RELATIVE") == "Relative",
                enabling=on and not pcomp.enabled,
            )
            pcomp.enabled = on
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
            value = clock.out_at(t)
            if toggled or value != out.value:
                out.value = value
                self.box.touch(out.key)
        for name, counter in self.counters.items():
            out = self.box.field(f"{name}.OUT")
            assert isinstance(out, PosOutField)
            out.set_live(wrap32(counter.value_at(t)))
        for name, pcomp in self.pcomps.items():
            fields = self.box.instances["PCOMP"][int(name[5:]) - 1].fields
            active, bit, state = fields["ACTIVE"], fields["OUT"], fields["STATE"]
            produced = fields["PRODUCED"]
            assert isinstance(active, BitOutField) and isinstance(bit, BitOutField)
            assert isinstance(state, EnumField) and isinstance(produced, NumberField)
            on = pcomp.active_at(t)
            active.set_live(on)
            state.set_live("WAIT_RISING" if on else "WAIT_ENABLE")
            value = pcomp.out_at(t)
            if pcomp.toggles(before, t) or value != bit.value:
                bit.value = value
                self.box.touch(bit.key)
            produced.set_live(pcomp.produced(t))

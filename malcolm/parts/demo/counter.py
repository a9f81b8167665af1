"""CounterPart: a counter with a delta, zero() and increment()."""

from __future__ import annotations

from malcolm.core import NumberMeta

from ..base import Part, PartRegistrar


class CounterPart(Part):
    """Adds ``counter`` and ``delta`` attributes and ``zero()``/``increment()``."""

    def setup(self, registrar: PartRegistrar) -> None:
        self.counter = registrar.add_attribute(
            "counter", NumberMeta("float64", "The current value", writeable=True), 0.0
        )
        self.delta = registrar.add_attribute(
            "delta", NumberMeta("float64", "How much to add", writeable=True), 1.0
        )
        registrar.add_method(self.zero)
        registrar.add_method(self.increment)

    def zero(self) -> None:
        """Set the counter to 0."""
        self.counter.set_value(0.0)

    def increment(self) -> None:
        """Add delta to the counter."""
        self.counter.set_value(self.counter.value + self.delta.value)

"""The simulated time of a box: a clock, the moving blocks, and PCAP.

`Simulation` is what the control-port `Session` calls: ``sync()`` before
every command (bring live values to now), ``wiring_changed()`` after every
write, and the ``*PCAP`` commands.  Time comes from a `Clock`: `RealClock`
(wall time) when serving, `ManualClock` in tests that step time themselves.
While an experiment runs, a task makes and sends its samples every few
milliseconds.
"""

from __future__ import annotations

import asyncio
import contextlib
import time
from typing import Protocol

from .box import Box
from .capture import Capture
from .signals import Signals
from .values import CLOCK_HZ

PUMP_PERIOD = 0.005


class Clock(Protocol):
    """Seconds since some start, never decreasing."""

    def now(self) -> float: ...


class RealClock:
    """Wall (monotonic) time since the clock was made."""

    def __init__(self) -> None:
        self._t0 = time.monotonic()

    def now(self) -> float:
        return time.monotonic() - self._t0


class ManualClock:
    """Time that moves only when `advance` is called."""

    def __init__(self) -> None:
        self.t = 0.0

    def now(self) -> float:
        return self.t

    def advance(self, seconds: float) -> None:
        self.t += seconds


class Simulation:
    """Signals and capture of one box, driven by a clock."""

    def __init__(
        self, box: Box, clock: Clock, disarm_completion: str = "Disarmed"
    ) -> None:
        self.box = box
        self.clock = clock
        self.signals = Signals(box)
        self.capture = Capture(box, self.signals, disarm_completion)
        self._pump: asyncio.Task | None = None

    def ticks(self) -> int:
        return int(self.clock.now() * CLOCK_HZ)

    def sync(self) -> None:
        """Bring every live value (and the capture) to now."""
        t = self.ticks()
        manual = isinstance(self.clock, ManualClock)
        self.capture.pump(t, limit=None if manual else 0)
        self.signals.advance(t)

    def wiring_changed(self) -> None:
        """After a write: apply it at the current time."""
        t = self.ticks()
        self.capture.pump(t, limit=None)
        self.signals.rewire(t)
        self.capture.rewire(t)
        self._ensure_pump()

    # -- *PCAP -------------------------------------------------------------
    def arm(self) -> None:
        t = self.ticks()
        self.signals.advance(t)
        self.capture.arm(t)
        self._ensure_pump()

    def disarm(self) -> None:
        self.capture.disarm(self.ticks())

    def status(self) -> str:
        return self.capture.status()

    def completion(self) -> str:
        return self.capture.completion

    def captured(self) -> str:
        return str(self.capture.captured)

    # -- background --------------------------------------------------------
    def _ensure_pump(self) -> None:
        if not self.capture.started or isinstance(self.clock, ManualClock):
            return
        if self._pump is None or self._pump.done():
            self._pump = asyncio.get_running_loop().create_task(self._run_pump())

    async def _run_pump(self) -> None:
        while self.capture.started:
            t = self.ticks()
            if self.capture.lagging(t):
                self.capture.overrun()
                break
            made = self.capture.pump(t)
            self.signals.advance(t)
            await asyncio.sleep(0 if made >= 65536 else PUMP_PERIOD)

    async def close(self) -> None:
        if self._pump is not None:
            self._pump.cancel()
            with contextlib.suppress(BaseException):
                await self._pump

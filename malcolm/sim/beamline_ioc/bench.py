"""Records for benchmarks/ca.py: many PVs to connect, and a fast ticker.

- ``P:B<b>:A<i>`` / ``_RBV`` for ``b`` < blocks, ``i`` < 10: ao/ai pairs
  (a put completes once the readback shows it): 20 PVs per block;
- ``P:BENCH:Ticker``: counts as fast as the IOC can post while
  ``P:BENCH:Run`` is 1.
"""

from __future__ import annotations

import asyncio
from typing import Any

from softioc import builder

PAIRS = 10  # demand/readback pairs per benchmark block


class Bench:
    def __init__(self, prefix: str, blocks: int) -> None:
        for b in range(blocks):
            builder.SetDeviceName(f"{prefix}:B{b}")
            for i in range(PAIRS):
                readback = builder.aIn(f"A{i}_RBV", initial_value=0.0)
                builder.aOut(
                    f"A{i}",
                    initial_value=0.0,
                    always_update=True,
                    blocking=True,
                    on_update=readback.set,
                )
        builder.SetDeviceName(f"{prefix}:BENCH")
        self.ticker = builder.longIn("Ticker", initial_value=0)
        self.run = builder.boolOut(
            "Run", ZNAM="Stop", ONAM="Run", on_update=self._run, always_update=True
        )
        self.task: Any = None

    def _run(self, value: int) -> None:
        if value and self.task is None:
            self.task = asyncio.ensure_future(self._tick())

    async def _tick(self) -> None:
        n = self.ticker.get()
        try:
            while self.run.get():
                n += 1
                self.ticker.set(n)
                await asyncio.sleep(0)
        finally:
            self.task = None

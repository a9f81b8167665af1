"""``benchmarks/ca_cost.py`` measures a put+readback's CPU through a block
and raw (against the session's IOC: a second IOC on this host is not found
by CA's unicast search while it runs; the benchmark's monitor figure needs
its own IOC's ticker and is run by the benchmark alone). Its figures depend
on the machine and are not asserted beyond being measured."""

from __future__ import annotations

import asyncio

from benchmarks import ca_cost
from malcolm.sim.beamline_ioc import SimIOC

from .conftest import PREFIX


def test_the_ca_cost_benchmark_measures_a_put_both_ways(ioc: SimIOC) -> None:
    import epics

    exposure = f"{PREFIX}:CAM:Exposure"
    original = epics.caget(exposure, timeout=5)
    try:
        ours, raw = asyncio.run(ca_cost.puts(20, 1, PREFIX))
    finally:  # the session IOC's value, for later modules
        epics.caput(exposure, original, wait=True)
    assert ours > 0 and raw > 0

"""Channel Access system tests: a simulated beamline IOC in a subprocess.

Run under ``../shared/tools/isolated`` (loopback only): the IOC and the
client find each other on 127.0.0.1 alone. The CA variables are set here, at
collection, before pyepics makes its context.
"""

from __future__ import annotations

import asyncio
import os
from collections.abc import Iterator
from contextlib import asynccontextmanager
from typing import Any

import pytest

from malcolm.config.build import build_definition
from malcolm.core import Process
from malcolm.sim.beamline_ioc import SimIOC, ca_environment

os.environ.update(ca_environment())

PREFIX = "CATEST"

#: block mri -> (definition, values): one of each hardware block
BLOCKS: dict[str, tuple[str, dict[str, Any]]] = {
    "DRV": ("ADCore.DetectorDriver", {"prefix": f"{PREFIX}:CAM"}),
    "POS": ("ADCore.PositionPlugin", {"prefix": PREFIX}),
    "HDF": ("ADCore.HDFWriter", {"prefix": PREFIX}),
    "M1": ("motor.MotorRecord", {"prefix": f"{PREFIX}:M1", "sep": ":"}),
    "M2": ("motor.MotorRecord", {"prefix": f"{PREFIX}:M2", "sep": ":"}),
    "TRAJ": ("pmac.TrajectoryScan", {"prefix": PREFIX}),
}


@pytest.fixture(scope="session")
def sim_ioc() -> Iterator[SimIOC]:
    """The simulated IOC of prefix CATEST, for the whole session."""
    ioc = SimIOC(PREFIX)
    ioc.start()
    yield ioc
    ioc.stop()


@pytest.fixture
def ioc(sim_ioc: SimIOC) -> SimIOC:
    """The session's IOC, started again if a test killed it."""
    if not sim_ioc.alive:
        sim_ioc.start()
    return sim_ioc


@pytest.fixture
def fresh_ioc(sim_ioc: SimIOC) -> SimIOC:
    """The session's IOC started anew, every PV at its default: for a test
    that reads the defaults, whatever earlier tests put (the managers'
    scans leave the driver with their exposure and trigger mode)."""
    if sim_ioc.alive:
        sim_ioc.stop()
    sim_ioc.start()
    return sim_ioc


def make_process(*mris: str) -> Process:
    """A process with the hardware blocks ``mris`` (all if none), on pyepics."""
    process = Process("ca-test", channels={"ca": "pyepics"})
    for mri in mris or tuple(BLOCKS):
        name, values = BLOCKS[mri]
        build_definition(name, values, mri, process=process)
    return process


@asynccontextmanager
async def started(*mris: str):
    process = make_process(*mris)
    await process.start()
    try:
        yield process
    finally:
        await process.stop()


def follow(process: Process, mri: str, field: str) -> list[Any]:
    """The values ``mri.field`` takes from now on (by its subscription)."""
    seen: list[Any] = []
    process.subscribe([mri, field, "value"], lambda delta: seen.append(delta[-1][1]))
    return seen


#: the tasks ``spawn`` made in the scenario ``run`` is running
_spawned: list[asyncio.Task[Any]] = []


def spawn(coro: Any) -> asyncio.Task[Any]:
    """``coro`` as a task the scenario awaits later (a move it stops...).

    If the scenario fails before awaiting it, :func:`run` ends it and takes
    its outcome, so that no "Task exception was never retrieved" (say the
    ``DisconnectedError`` of a put whose channel the process closed) is left
    to fail whichever later test the garbage collector runs in."""
    task = asyncio.ensure_future(coro)
    _spawned.append(task)
    return task


async def _settle_spawned() -> None:
    tasks, _spawned[:] = list(_spawned), []
    for task in tasks:
        task.cancel()  # a no-op once done
    for task in tasks:
        try:
            await task
        except BaseException:  # the scenario's own error is what counts
            pass


def run(coro: Any, timeout: float = 60) -> Any:
    """Run the scenario ``coro`` on a new loop, at most ``timeout`` s; tasks
    it spawned and did not await are ended and their outcomes taken."""

    async def scenario() -> Any:
        try:
            return await asyncio.wait_for(coro, timeout)
        except BaseException:
            await _settle_spawned()
            raise
        finally:
            _spawned.clear()  # passed: it awaited what it spawned

    return asyncio.run(scenario())


async def until(predicate: Any, timeout: float = 10.0, what: str = "") -> float:
    """Wait until ``predicate()`` is true; seconds it took. Fails the test
    (naming ``what``) after ``timeout`` seconds."""
    loop = asyncio.get_running_loop()
    began = loop.time()
    while not predicate():
        if loop.time() - began > timeout:
            raise AssertionError(f"not within {timeout} s: {what}")
        await asyncio.sleep(0.01)
    return loop.time() - began

"""Simulated parts pace their points against fixed deadlines (issue 8), so a
scan's overhead does not grow with its length.

The clock here is a fake one whose every sleep overshoots by OVERSHOOT, as
a real timer does: a run paced against deadlines ends its total duration
plus one overshoot after it started, whatever its length; one that sleeps a
duration per point would end a whole overshoot later per point. No test
here measures real time.
"""

from __future__ import annotations

import asyncio

import pytest

from malcolm.controllers.runnable import RunnableController
from malcolm.controllers.stateful import StatefulController
from malcolm.core import Process
from malcolm.parts import pacing
from malcolm.parts.demo import MotorMovePart, SimDetectorPart, SimMotorPart
from malcolm.scan import gda
from malcolm.sim.position_plugin import SoftPositionPluginPart

OVERSHOOT = 0.0005


class FakeClock:
    """``now`` moves only when something sleeps: by the delay asked plus
    OVERSHOOT, as a timer that always wakes late."""

    def __init__(self) -> None:
        self.now = 1000.0
        self.sleeps: list[float] = []

    def time(self) -> float:
        return self.now

    async def sleep(self, delay: float) -> None:
        self.sleeps.append(delay)
        self.now += delay + OVERSHOOT
        await asyncio.sleep(0)


@pytest.fixture
def clock(monkeypatch: pytest.MonkeyPatch) -> FakeClock:
    fake = FakeClock()
    monkeypatch.setattr(pacing, "_now", fake.time)
    monkeypatch.setattr(pacing, "_sleep", fake.sleep)
    return fake


def test_deadlines_make_up_for_a_late_point(clock: FakeClock) -> None:
    async def run() -> float:
        start = clock.now
        deadlines = pacing.Deadlines()
        for i in range(1000):
            await deadlines.wait(0.001)
            if i == 10:
                clock.now += 0.0035  # one point's work took 3.5 ms
        return clock.now - start

    elapsed = asyncio.run(run())
    assert elapsed == pytest.approx(1.0 + OVERSHOOT)
    # behind time it still yields to the loop, asking for no wait
    assert len(clock.sleeps) == 1000
    assert clock.sleeps.count(0.0) >= 3


def scan_time(process: Process, mri: str, points: int, duration: float) -> float:
    """Fake seconds a configured and run scan of ``points`` took."""

    async def run() -> float:
        await process.start()
        try:
            generator = gda.compound(gda.line("x", points), duration=duration)
            await process.post([mri, "configure"], {"generator": generator})
            start = pacing._now()
            await process.post([mri, "run"])
            assert process.get_block(mri).state.value == "Finished"
            return pacing._now() - start
        finally:
            await process.stop()

    return asyncio.run(run())


@pytest.mark.parametrize("points", [20, 400])
def test_a_detector_run_lasts_its_total_duration_plus_one_overshoot(
    clock: FakeClock, points: int
) -> None:
    process = Process("t")
    process.add_controller(RunnableController("DET", [SimDetectorPart("det")]))
    elapsed = scan_time(process, "DET", points, 0.01)
    assert elapsed == pytest.approx(points * 0.01 + OVERSHOOT)
    assert process.get_block("DET").framesTaken.value == points


@pytest.mark.parametrize("points", [20, 400])
def test_motor_moves_are_paced_the_same_way(clock: FakeClock, points: int) -> None:
    process = Process("t")
    # fast enough to arrive at once: only the scan's pacing sleeps
    process.add_controller(StatefulController("M", [SimMotorPart(velocity=1e9)]))
    process.add_controller(
        RunnableController("SCAN", [MotorMovePart("x", mri="M", axis="x")])
    )
    elapsed = scan_time(process, "SCAN", points, 0.02)
    assert elapsed == pytest.approx(points * 0.02 + OVERSHOOT)
    assert process.get_block("M").position.value == 1.0


def test_the_position_plugin_tags_frames_at_its_frame_rate(clock: FakeClock) -> None:
    plugin = SoftPositionPluginPart("plugin", frame_period=0.001, idle_time=0.01)
    process = Process("t")
    process.add_controller(StatefulController("POS", [plugin]))

    async def run() -> float:
        await process.start()
        try:
            await process.put(["POS", "enableCallbacks"], True)
            await process.put(["POS", "xml"], "<position/>" * 300)
            start = pacing._now()
            await process.put(["POS", "start"], True)
            return pacing._now() - start
        finally:
            await process.stop()

    elapsed = asyncio.run(run())
    assert process.get_block("POS").processed.value == 300
    frames = len(clock.sleeps)  # 300 tagged, then the idle ones
    assert frames >= 300
    assert elapsed == pytest.approx(frames * 0.001 + OVERSHOOT)

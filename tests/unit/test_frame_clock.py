"""The DetectorManager's frame clock: the driver's frame counter at the last
frame counted is inferred from its value at the run's start and the frames
counted, not read when the count came (detector_manager.FrameClock).

Seen under load (tests/system/ca/test_detmgr_timeout.py, 1 run in 25 with
two CPU hogs): the writer's NumCaptured_RBV 31 arrived while the driver's
ArrayCounter_RBV still read 29 (the IOC posts each at most every 5 ms, on
its own timer), so a detector stopped after frame 31 was reported as
"made 2 frames since: its frames do not reach the writer"."""

from __future__ import annotations

import asyncio

from malcolm.parts.detector_manager import FrameClock, stall_message


def clock_after(first: int, made: int, counts: list[int]) -> FrameClock:
    async def scenario() -> FrameClock:
        clock = FrameClock(first, made)
        for count in counts:
            clock.saw(count)
        return clock

    return asyncio.run(scenario())


def test_the_writers_count_coming_before_the_drivers_counter_loses_no_frame():
    # the counter read 29 when the writer's 31 came; 31 by the stall
    clock = clock_after(0, 0, [1, 2, 28, 31])
    assert (clock.count, clock.made) == (31, 31)
    text = stall_message(
        "DET", 1.0, clock, "Internal", "Idle", acquiring=False, made=31 - clock.made
    )
    assert text.endswith(
        "made 0 frames since: the detector stopped before the run's frames were taken"
    ), text


def test_frames_made_beyond_those_counted_are_the_frames_that_did_not_arrive():
    # a resumed run from step 8, the counter at 100 when it started: 5
    # frames counted, the counter at 112 by the stall
    clock = clock_after(8, 100, [9, 13, 12])
    assert (clock.count, clock.made) == (13, 105)
    text = stall_message(
        "DET", 1.0, clock, "Internal", "Idle", acquiring=False, made=112 - clock.made
    )
    assert "made 7 frames since: its frames do not reach the writer" in text


def test_no_frame_counted_leaves_the_counter_of_the_runs_start():
    clock = clock_after(4, 50, [4, 3])
    assert (clock.count, clock.made) == (4, 50)

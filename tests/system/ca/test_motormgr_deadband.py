"""The simulated motors' retry deadband (RDBD), and a scan configured again:
the MotorControllerManager leaves a motor already at its run-up start where
it is, and sends no array the controller holds already."""

from __future__ import annotations

import pytest

from .conftest import follow, run, started
from .motormgr import MRI, line, manager_process


def test_a_put_within_the_deadband_moves_nothing_and_one_past_it_moves(ioc):
    async def scenario():
        async with started("M1") as process:
            m1 = process.get_block("M1")
            deadband = m1.deadband.value
            assert deadband == pytest.approx(1e-4)
            await process.put(["M1", "position"], 0.5)
            done = follow(process, "M1", "doneMoving")  # [True] at once
            await process.put(["M1", "position"], 0.5 + deadband / 2)
            assert m1.position.value == pytest.approx(0.5)  # it stayed
            assert done == [True]  # DMOV never dropped: no move
            await process.put(["M1", "position"], 0.5 + deadband * 3)
            assert m1.position.value == pytest.approx(0.5 + deadband * 3)
            assert False in done  # a move, however short

    run(scenario())


def test_a_configure_to_where_the_motors_are_issues_no_move(ioc):
    process = manager_process()

    async def scenario():
        await process.start()
        try:
            # x from 1.0: its run-up start is 1.0 less a half step less the
            # acceleration distance
            await process.post([MRI, "configure"], {"generator": line(20, 1.0, 3.0)})
            a = process.get_block(f"{MRI}:a")
            there = a.position.value
            await process.post([MRI, "reset"])
            done = follow(process, f"{MRI}:a", "doneMoving")
            puts = follow(process, f"{MRI}:a", "position")
            # the same scan 1e-6 s a point slower: the start moves by
            # nanometres, within the deadband
            await process.post(
                [MRI, "configure"],
                {"generator": line(20, 1.0, 3.0, duration=0.01 + 1e-6)},
            )
            assert process.get_block(MRI).state.value == "Armed"
            # nothing was put (a put shows its readback again) or moved
            assert done == [True] and puts == [there]
            assert a.position.value == there
            await process.post([MRI, "reset"])
            # from 2.0: a move
            await process.post([MRI, "configure"], {"generator": line(20, 2.0, 4.0)})
            assert False in done
            assert a.position.value == pytest.approx(there + 1.0, abs=1e-3)
        finally:
            await process.stop()

    run(scenario())


def test_arrays_the_controller_holds_are_not_sent_again_but_built(ioc, tmp_path):
    process = manager_process()
    calls: list[tuple[str, ...]] = []  # the puts and calls to the trajectory
    put, post = process.put, process.post

    async def putting(path: list[str], value: object) -> None:
        calls.append(("put", *path))
        await put(path, value)

    async def posting(path: list[str], *args: object) -> object:
        calls.append(("call", *path))
        return await post(path, *args)

    process.put, process.post = putting, posting  # type: ignore[method-assign]
    traj = f"{MRI}:traj"

    async def scenario():
        await process.start()
        try:
            block = process.get_block(MRI)
            for start in (0.37, 1.0):  # whatever the IOC held: new positions
                calls.clear()
                generator = line(20, start, start + 2.0)
                await process.post([MRI, "configure"], {"generator": generator})
                assert ("put", traj, "positionsA") in calls
                await process.post([MRI, "reset"])
            calls.clear()
            await process.post(
                [MRI, "configure"],
                {"generator": line(20, 1.0, 3.0), "fileDir": str(tmp_path)},
            )
            assert block.state.value == "Armed"
            # nothing sent again, the profile built all the same
            assert not [c for c in calls if c[0] == "put" and c[1] == traj]
            assert ("call", traj, "buildProfile") in calls
            await process.post([MRI, "run"])
            assert block.completedSteps.value == 20
            await process.post([MRI, "reset"])
            calls.clear()
            # another scan: its arrays go
            await process.post([MRI, "configure"], {"generator": line(20, 2.0, 4.0)})
            assert ("put", traj, "positionsA") in calls
        finally:
            await process.stop()

    run(scenario())

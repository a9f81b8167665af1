"""The simulated box killed in the middle of a ZebraManager's run: the run
fails at once and the block is in Fault with a ``health`` naming the box; a
reset while the box is away fails the same way; once it is back, reset
gives Ready and a new scan runs."""

from __future__ import annotations

import asyncio

from malcolm.core import MalcolmError
from malcolm.scan import gda

from .zebramgr import MRI, read_elsewhere, wait_for, zebra_process


def test_the_box_killed_mid_run_faults_naming_it_and_reset_recovers(sim, tmp_path):
    address = f"Zebra2 box {sim.host}:{sim.control_port}"

    async def main():
        process = zebra_process(sim)
        await process.start()
        loop = asyncio.get_running_loop()
        try:
            block = process.get_block(MRI)
            generator = gda.compound(gda.line("x", 1000), duration=0.01)
            params = {"generator": generator, "fileDir": str(tmp_path)}
            await process.post([MRI, "configure"], params)
            run = asyncio.ensure_future(process.post([MRI, "run"]))
            await wait_for(block, "completedSteps", lambda v: v >= 10)
            await loop.run_in_executor(None, sim.kill)
            try:
                await asyncio.wait_for(run, 10)  # promptly: never a hang
                raise AssertionError("the run did not fail")
            except MalcolmError as e:
                error = str(e)
            fault = (block.state.value, block.health.value)
            rows = read_elsewhere(tmp_path / "zebra.h5")["uniqueid"]
            try:
                await process.post([MRI, "reset"])
                raise AssertionError("reset with no box did not fail")
            except MalcolmError:
                pass
            still = (block.state.value, block.health.value)
            await loop.run_in_executor(None, sim.start)
            await process.post([MRI, "reset"])
            # the children's poll finds the box again within a poll or two
            await wait_for(block, "health", lambda v: v == "OK", timeout=5)
            ready = (block.state.value, block.health.value)
            small = gda.compound(gda.line("x", 12), duration=0.002)
            await process.post([MRI, "configure"], {**params, "generator": small})
            await process.post([MRI, "run"])
            return error, fault, rows, still, ready, block.state.value
        finally:
            await process.stop()

    error, fault, rows, still, ready, state = asyncio.run(main())
    assert address in error
    assert fault[0] == "Fault" and address in fault[1], fault
    assert rows == list(range(1, len(rows) + 1)) and len(rows) >= 10
    # a reset's failure is this part's or the children's (zebra2.Manager),
    # whichever fails first: either names the box's address
    box = f"{sim.host}:{sim.control_port}"
    assert still[0] == "Fault" and box in still[1], still
    assert ready == ("Ready", "OK")
    assert state == "Finished"
    assert read_elsewhere(tmp_path / "zebra.h5")["uniqueid"] == list(range(1, 13))


def test_a_box_that_is_not_there_faults_at_start_naming_it(sim, tmp_path):
    sim.kill()
    # this part's failure or the children's (zebra2.Manager), whichever
    # fails first: either names the box's address
    address = f"{sim.host}:{sim.control_port}"

    async def main():
        process = zebra_process(sim, timeout=1.0)
        await process.start()
        try:
            block = process.get_block(MRI)
            return block.state.value, block.health.value
        finally:
            await process.stop()

    state, health = asyncio.run(main())
    assert state == "Fault" and address in health, (state, health)


def test_the_box_killed_while_armed_fails_the_run_at_once(sim, tmp_path):
    address = f"Zebra2 box {sim.host}:{sim.control_port}"

    async def main():
        process = zebra_process(sim)
        await process.start()
        loop = asyncio.get_running_loop()
        try:
            block = process.get_block(MRI)
            generator = gda.compound(gda.line("x", 20), duration=0.01)
            params = {"generator": generator, "fileDir": str(tmp_path)}
            await process.post([MRI, "configure"], params)
            await loop.run_in_executor(None, sim.kill)
            try:
                await asyncio.wait_for(process.post([MRI, "run"]), 10)
                raise AssertionError("the run did not fail")
            except MalcolmError as e:
                error = str(e)
            return error, block.state.value, block.health.value
        finally:
            await process.stop()

    error, state, health = asyncio.run(main())
    assert address in error
    assert state == "Fault" and address in health, (state, health)
    assert read_elsewhere(tmp_path / "zebra.h5")["uniqueid"] == []

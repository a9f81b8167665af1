"""The demo motor refuses a velocity or demand that would leave its position
NaN for ever and hang every later scan (issue 7 item 9)."""

from __future__ import annotations

import math

import pytest

from malcolm.config import ConfigError
from malcolm.config.build import build_definition
from malcolm.core import BadValueError
from malcolm.demo import demo_process, run_demo_scan

from .scans import run


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf, 0.0, -5.0])
def test_a_bad_velocity_is_refused_at_the_put_and_scans_still_finish(bad, capsys):
    async def scenario():
        process = demo_process()
        await process.start()
        try:
            with pytest.raises(BadValueError) as info:
                await process.put(["MOTOR:X", "velocity"], bad)
            motor = process.get_block("MOTOR:X")
            velocity = motor.velocity.value
            await process.put(["MOTOR:X", "demand"], 0.5)
            await run_demo_scan(process)
            return str(info.value), velocity, motor.position.value
        finally:
            await process.stop()

    message, velocity, position = run(scenario)
    assert message == (
        f"MOTOR:X.velocity: must be a positive, finite number of units/s, not {bad!r}"
    )
    assert velocity == 100.0
    assert math.isfinite(position)
    assert capsys.readouterr().out.rstrip().endswith("SCAN Finished")


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_a_demand_that_is_not_finite_is_refused(bad):
    async def scenario():
        process = demo_process()
        await process.start()
        try:
            with pytest.raises(BadValueError) as info:
                await process.put(["MOTOR:Y", "demand"], bad)
            motor = process.get_block("MOTOR:Y")
            return str(info.value), motor.demand.value, motor.position.value
        finally:
            await process.stop()

    message, demand, position = run(scenario)
    assert message == f"MOTOR:Y.demand: must be a finite position, not {bad!r}"
    assert (demand, position) == (0.0, 0.0)


def test_a_good_velocity_is_taken():
    async def scenario():
        process = demo_process()
        await process.start()
        try:
            await process.put(["MOTOR:X", "velocity"], 250)
            return process.get_block("MOTOR:X").velocity.value
        finally:
            await process.stop()

    assert run(scenario) == 250.0


def test_a_motor_defined_with_a_nan_velocity_is_refused_at_its_line():
    with pytest.raises(ConfigError) as info:
        build_definition("demo.Motor", {"velocity": math.nan}, "M")
    (problem,) = info.value.problems
    assert problem.file.endswith("demo/Motor.yaml") and problem.line == 15
    assert problem.message == (
        "parts.SimMotorPart: velocity must be a positive, finite number of units/s,"
        " not nan"
    )

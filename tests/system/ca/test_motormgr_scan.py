"""The MotorControllerManager on the simulated IOC: lines and snake grids as
trajectories with a run-up, the raw file, and validate's refusals."""

from __future__ import annotations

import math

import numpy as np
import pytest

from malcolm.core import MalcolmError
from malcolm.scan import gda

from .conftest import follow, run
from .motormgr import MRI, line, manager_process, read_file, snake


def test_a_line_runs_as_a_trajectory_into_the_file(ioc, tmp_path):
    process = manager_process()

    async def scenario():
        await process.start()
        try:
            block = process.get_block(MRI)
            assert block.state.value == "Ready"
            assert list(block.simultaneousAxes.value) == ["x", "y"]
            m1 = process.get_block(f"{MRI}:a")
            positions = follow(process, f"{MRI}:a", "position")
            await process.post(
                [MRI, "configure"],
                {"generator": line(20, 1.0, 3.0), "fileDir": str(tmp_path)},
            )
            assert block.state.value == "Armed"
            # the run-up: half a step before the first point, less the
            # acceleration distance (0.1 s at 2.0/19 per 0.01 s)
            speed = (2.0 / 19) / 0.01
            assert m1.position.value == pytest.approx(1.0 - 1 / 19 - speed * 0.05)
            rows = block.datasets.value
            assert list(rows["name"]) == ["x.value_set", "x.value"]
            assert list(rows["type"]) == ["position_set", "position_value"]
            assert list(rows["filename"]) == ["motors.h5"] * 2
            assert list(rows["rank"]) == [0, 0]
            assert list(rows["uniqueid"]) == ["/entry/uniqueid"] * 2
            await process.post([MRI, "run"])
            assert block.state.value == "Finished"
            assert block.completedSteps.value == 20
            # the motor ends at the end of the last point
            assert m1.position.value == pytest.approx(3.0 + 1 / 19)
            assert min(positions) < 1.0  # it started before the first point
        finally:
            await process.stop()

    run(scenario())
    data = read_file(str(tmp_path / "motors.h5"), ["x"])
    assert list(data["uniqueid"]) == list(range(1, 21))
    assert np.allclose(data["x.value_set"], np.linspace(1.0, 3.0, 20))
    assert np.allclose(data["x.value"], data["x.value_set"], atol=1e-3)


def test_a_snake_grid_turns_round_between_rows(ioc, tmp_path):
    process = manager_process()

    async def scenario():
        await process.start()
        try:
            block = process.get_block(MRI)
            m1, m2 = process.get_block(f"{MRI}:a"), process.get_block(f"{MRI}:b")
            await process.post(
                [MRI, "configure"],
                {"generator": snake(3, 5), "fileDir": str(tmp_path)},
            )
            traj = process.get_block(f"{MRI}:traj")
            # 15 points: run-up, midpoint and end of each, two turnarounds
            assert traj.numPoints.value == 1 + 2 * 15 + 2
            assert sorted(block.datasets.value["name"]) == [
                "x.value",
                "x.value_set",
                "y.value",
                "y.value_set",
            ]
            await process.post([MRI, "run"])
            assert block.state.value == "Finished"
            # the third row runs forwards again: it ends half a step past x=2
            assert m1.position.value == pytest.approx(2.25)
            assert m2.position.value == pytest.approx(1.0)
        finally:
            await process.stop()

    run(scenario())
    data = read_file(str(tmp_path / "motors.h5"), ["x", "y"])
    assert list(data["uniqueid"]) == list(range(1, 16))
    xs = [0.0, 0.5, 1.0, 1.5, 2.0]
    assert np.allclose(data["x.value_set"], xs + xs[::-1] + xs)
    assert np.allclose(data["y.value_set"], [0.0] * 5 + [0.5] * 5 + [1.0] * 5)
    for axis in ("x", "y"):
        assert np.allclose(data[f"{axis}.value"], data[f"{axis}.value_set"], atol=1e-3)


def test_validate_refuses_a_point_faster_than_the_motor_names_the_axis(ioc):
    process = manager_process()

    async def scenario():
        await process.start()
        try:
            await process.put([f"{MRI}:a", "maxVelocity"], 50.0)
            fast = line(11, 0.0, 10.0, duration=0.01)  # 1 mm in 10 ms: 100 mm/s
            with pytest.raises(MalcolmError) as info:
                await process.post([MRI, "validate"], {"generator": fast})
            message = str(info.value)
            assert f"axis x ({MRI}:a) needs 100/s" in message
            assert "maximum velocity 50/s" in message
            with pytest.raises(MalcolmError, match="axis x"):
                await process.post([MRI, "configure"], {"generator": fast})
            assert process.get_block(MRI).state.value == "Ready"  # refused
            # slow enough: taken
            slow = line(11, 0.0, 10.0, duration=0.05)
            await process.post([MRI, "validate"], {"generator": slow})
            # outside the motor's limits: refused too
            far = line(11, 0.0, 150.0, duration=1.0)
            with pytest.raises(MalcolmError, match=r"axis x .*outside its limits"):
                await process.post([MRI, "validate"], {"generator": far})
        finally:
            await process.put([f"{MRI}:a", "maxVelocity"], 1000.0)
            await process.stop()

    run(scenario())


def test_a_grid_run_row_by_row_prepares_each_row(ioc, tmp_path):
    process = manager_process()

    async def scenario():
        await process.start()
        try:
            block = process.get_block(MRI)
            m2 = process.get_block(f"{MRI}:b")
            params = {
                "generator": snake(3, 4),
                "axesToMove": ["x"],
                "fileDir": str(tmp_path),
                "formatName": "rows",
            }
            await process.post([MRI, "configure"], params)
            traj = process.get_block(f"{MRI}:traj")
            assert traj.numPoints.value == 1 + 2 * 4  # one row
            for row in range(3):
                assert block.configuredSteps.value == 4 * (row + 1)
                # Armed for the row: y is at the row's position
                assert m2.position.value == pytest.approx(0.5 * row)
                await process.post([MRI, "run"])
            assert block.state.value == "Finished"
        finally:
            await process.stop()

    run(scenario())
    data = read_file(str(tmp_path / "rows.h5"), ["x", "y"])
    assert list(data["uniqueid"]) == list(range(1, 13))
    # y stayed at its row's position while x ran the row
    assert np.allclose(data["y.value"], np.repeat([0.0, 0.5, 1.0], 4), atol=1e-3)
    assert np.allclose(data["x.value"], data["x.value_set"], atol=1e-3)


def test_file_arguments_that_cannot_work_are_refused_naming_them(ioc, tmp_path):
    process = manager_process()

    async def scenario():
        await process.start()
        try:
            (tmp_path / "plain").write_text("not a directory")
            cases = [
                ({"fileDir": str(tmp_path / "plain" / "sub")}, "fileDir"),
                ({"fileDir": str(tmp_path), "formatName": "../up"}, "formatName"),
            ]
            for extra, named in cases:
                with pytest.raises(MalcolmError, match=f"configure.{named}: "):
                    await process.post(
                        [MRI, "configure"], {"generator": line(5), **extra}
                    )
                assert process.get_block(MRI).state.value == "Ready"
            # a directory that does not exist yet is made
            where = tmp_path / "new" / "dir"
            await process.post(
                [MRI, "configure"], {"generator": line(5), "fileDir": str(where)}
            )
            assert (where / "motors.h5").exists()
        finally:
            await process.stop()

    run(scenario())


def test_a_spiral_runs_and_one_of_10000_points_loads_whole(ioc, tmp_path):
    process = manager_process()

    async def scenario():
        await process.start()
        try:
            block = process.get_block(MRI)
            traj = process.get_block(f"{MRI}:traj")
            spiral = gda.compound(gda.spiral("x", "y", 1.0, 0.1), duration=0.005)
            await process.post(
                [MRI, "configure"], {"generator": spiral, "fileDir": str(tmp_path)}
            )
            size = block.totalSteps.value
            assert traj.numPoints.value == 2 * size + 1  # every point meets the next
            await process.post([MRI, "run"])
            assert block.state.value == "Finished"
            # 10,000 points: 20,001 profile points in the controller at once
            radius = 0.1 * math.sqrt(9999.5 / math.pi)
            big = gda.compound(gda.spiral("x", "y", radius, 0.1), duration=0.01)
            await process.post([MRI, "configure"], {"generator": big})
            assert block.totalSteps.value == 10_000
            assert traj.numPoints.value == 20_001
            assert list(traj.positionsA.value[:3]) == pytest.approx(
                process.get_controller(MRI)
                .parts["trajectory"]
                .profile.positions["x"][:3]
            )
            return size
        finally:
            await process.stop()

    size = run(scenario())
    data = read_file(str(tmp_path / "motors.h5"), ["x", "y"])
    assert list(data["uniqueid"]) == list(range(1, size + 1))
    for axis in ("x", "y"):
        assert np.allclose(data[f"{axis}.value"], data[f"{axis}.value_set"], atol=1e-3)

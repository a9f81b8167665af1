"""The BeamlineManager definition over three runnable device managers that
keep the device contract (configure takes fileDir/formatName, raw files with
a uniqueid per row, a ``datasets`` table): configure hands each child its
arguments at once, the motion starts last, pause/seek/resume gives one row
per point in the scan's file, a child's fault names the child."""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pytest

from malcolm.beamline import add_beamline_manager
from malcolm.core import BadValueError, MalcolmError, NumberMeta, Process, StringMeta
from malcolm.fsm import RunnableDevice
from malcolm.hooks import Task
from malcolm.parts import Part, PartRegistrar
from malcolm.parts.coordination import datasets_meta
from malcolm.parts.demo.steps import run_steps
from malcolm.scan import gda, scan_points

from .scans import run

ORDER: list[str] = []  # which device started its run when
SEEKS: list[str] = []  # "<device> <begin|end>" of each device's Seek


class FakeDevicePart(Part):
    """A device manager's contract in memory: one row per point done (its
    uid and a value), written to <fileDir>/<formatName>.h5 when a run ends
    or is aborted; ``fail_at``: the step at which its run fails."""

    def __init__(self, name: str, dataset: str, kind: str, rank: int = 0) -> None:
        super().__init__(name)
        self.dataset, self.kind, self.rank = dataset, kind, rank
        self.rows: list[tuple[int, float]] = []
        self.fail_at: int | None = None
        self.got: dict[str, Any] = {}

    def setup(self, registrar: PartRegistrar) -> None:
        registrar.add_configure_arg("fileDir", StringMeta("dir"), "")
        registrar.add_configure_arg("formatName", StringMeta("name"), self.name)
        self.datasets = registrar.add_attribute("datasets", datasets_meta())
        self.count = registrar.add_attribute("rowsWritten", NumberMeta("int32"), 0)
        if self.kind == "primary":  # as the DetectorManager does
            registrar.add_configure_arg("frameTimeout", NumberMeta("float64"), 0.0)
        if self.kind == "position_value":
            registrar.controller.block.simultaneousAxes.set_value(["x", "y"])

    @property
    def path(self) -> Path:
        return Path(self.got["fileDir"]) / f"{self.got['formatName']}.h5"

    @RunnableDevice.Configure
    async def configure(self, task: Task, device: Any) -> None:
        self.got = dict(device.params)
        self.rows = []
        name = f"{self.got['formatName']}.h5"
        self.datasets.set_value(
            {"name": [self.dataset.format(fmt=self.got["formatName"])],
             "filename": [name], "type": [self.kind],
             "rank": [self.rank], "path": ["/data"], "uniqueid": ["/uid"]}
        )  # fmt: skip

    @RunnableDevice.Run
    async def run(self, task: Task, device: Any) -> None:
        ORDER.append(self.name)
        try:
            steps = run_steps(
                device.points, device.completedSteps, device.configuredSteps
            )
            for step, _, _ in steps:
                await asyncio.sleep(0.002)
                if self.fail_at == step:
                    raise RuntimeError(f"lost {self.name} at step {step}")
                self.rows.append((step + 1, 10.0 * (step + 1) + len(self.rows) / 1000))
                task.report_progress(step + 1)
        finally:
            self.write()

    @RunnableDevice.Seek
    async def seek(self) -> None:
        SEEKS.append(f"{self.name} begin")
        # the motion takes a while to stop (it decelerates)
        await asyncio.sleep(0.05 if self.name == "motors" else 0.001)
        SEEKS.append(f"{self.name} end")

    @RunnableDevice.Abort
    async def abort(self) -> None:
        self.write()

    def write(self) -> None:
        if not self.got.get("fileDir"):
            return
        uids = np.array([u for u, _ in self.rows], np.int32)
        values = np.array([v for _, v in self.rows])
        if self.rank:
            values = values[:, None, None] * np.ones((1, 2, 2))
        with h5py.File(self.path, "w") as f:
            f["data"] = values
            f["uid"] = uids
        self.count.set_value(len(self.rows))


async def make(tmp_path: Path) -> tuple[Process, dict[str, FakeDevicePart]]:
    process = Process()
    devices = {
        # named as pymalcolm's detectors name it: under their formatName
        "DET": FakeDevicePart("det", "{fmt}.data", "primary", 2),
        "MOTORS": FakeDevicePart("motors", "x.value", "position_value"),
        "ZEBRA": FakeDevicePart("zebra", "panda.INENC1.VAL", "monitor"),
    }
    add_beamline_manager(process, {mri: [part] for mri, part in devices.items()})
    await process.start()
    ORDER.clear()
    SEEKS.clear()
    return process, devices


#: spiral radius -> its number of points (rings 1 apart)
SIZES = {2.0: 13, 3.6: 41, 11.3: 402}


def spiral(radius: float = 2.0) -> dict[str, Any]:
    """A spiral as GDA sends it (``SIZES[radius]`` points)."""
    gen = gda.compound(gda.spiral("x", "y", radius), duration=0.001)
    assert scan_points(gen).size == SIZES[radius]
    return gen


def test_configure_hands_each_child_its_arguments(tmp_path):
    async def scenario():
        p, devices = await make(tmp_path)
        assert list(p.get(["BL", "simultaneousAxes", "value"])) == ["x", "y"]
        defaults = p.get(["BL", "configure", "meta", "defaults"])
        assert defaults["fileTemplate"] == "%s.nxs" and defaults["fileDir"] == ""
        assert defaults["frameTimeout"] == 0.0
        await p.post(["BL", "configure"], {"generator": spiral(),
                     "axesToMove": ["x", "y"], "fileDir": str(tmp_path),
                     "formatName": "s1", "frameTimeout": 2.5})  # fmt: skip
        assert p.get(["BL", "state", "value"]) == "Armed"
        # the detector alone takes the frame timeout
        assert devices["DET"].got["frameTimeout"] == 2.5
        assert "frameTimeout" not in devices["MOTORS"].got
        for name, part in devices.items():
            assert part.got["fileDir"] == str(tmp_path)
            assert part.got["formatName"] == f"s1-{name.lower()}"
            assert list(part.got["axesToMove"]) == ["x", "y"]
        table = p.get(["BL", "datasets", "value"])
        assert set(table["path"]) == {
            "/entry/det/data",
            "/entry/x/value",
            "/entry/panda/INENC1.VAL",
            "/entry/x/value_set",
            "/entry/y/value_set",
        }
        assert set(table["filename"]) == {"s1.nxs"}

    run(scenario)


def test_pause_seek_resume_gives_one_row_per_point(tmp_path):
    async def scenario():
        p, devices = await make(tmp_path)
        await p.post(["BL", "configure"], {"generator": spiral(3.6),
                     "axesToMove": ["x", "y"], "fileDir": str(tmp_path),
                     "formatName": "s2"})  # fmt: skip
        running = asyncio.ensure_future(p.post(["BL", "run"]))
        while p.get(["BL", "completedSteps", "value"]) < 20:
            await asyncio.sleep(0.005)
        await p.post(["BL", "pause"], {"lastGoodStep": 10})
        assert p.get(["BL", "state", "value"]) == "Paused"
        assert p.get(["BL", "completedSteps", "value"]) == 10
        await p.post(["BL", "resume"])
        await running
        assert p.get(["BL", "state", "value"]) == "Finished"
        # the motion started after the detector and the Zebra, both times
        assert ORDER[2] == "motors" and ORDER[-1] == "motors", ORDER
        # and stopped first: its pause ended before the others' began
        assert SEEKS[:2] == ["motors begin", "motors end"], SEEKS
        assert sorted(SEEKS[2:]) == ["det begin", "det end", "zebra begin",
                                     "zebra end"]  # fmt: skip
        det = devices["DET"]
        assert len(det.rows) > 41  # points 10.. were done twice
        with h5py.File(tmp_path / "s2.nxs", "r") as f:
            assert f["/entry/uniqueid"][()].tolist() == list(range(1, 42))
            frames = f["/entry/det/data"][()]
            assert frames.shape == (41, 2, 2)
            # one frame per point: its own uid, the later one of a re-done point
            assert (frames[:, 0, 0] // 10).astype(int).tolist() == list(range(1, 42))
            last = {u: v for u, v in det.rows}
            assert frames[:, 0, 0].tolist() == [last[u] for u in range(1, 42)]
            assert f["/entry/x/value_set"].shape == (41,)
            assert f["/entry/det"].attrs["NX_class"] == "NXdata"

    run(scenario)


def test_a_child_fault_ends_the_scan_in_fault_naming_it(tmp_path):
    async def scenario():
        p, devices = await make(tmp_path)
        devices["ZEBRA"].fail_at = 5
        await p.post(["BL", "configure"], {"generator": spiral(3.6),
                     "axesToMove": ["x", "y"], "fileDir": str(tmp_path)})  # fmt: skip
        with pytest.raises(MalcolmError, match="ZEBRA: .*lost zebra at step 5"):
            await p.post(["BL", "run"])
        assert p.get(["BL", "state", "value"]) == "Fault"
        assert p.get(["BL", "health", "value"]).startswith("ZEBRA: ")
        assert "lost zebra at step 5" in p.get(["BL", "health", "value"])
        # the file is written from the rows taken before the fault
        for _ in range(500):
            if (tmp_path / "bl.nxs").exists():
                break
            await asyncio.sleep(0.01)
        with h5py.File(tmp_path / "bl.nxs", "r") as f:
            assert f["/entry"].attrs["fault"].startswith("ZEBRA: ")
            uid = f["/entry/uniqueid"][()].tolist()
            assert uid[:5] == [1, 2, 3, 4, 5] and 0 in uid
        # the others were stopped, not left running
        for _ in range(100):
            if p.get(["BL:MOTORS", "state", "value"]) == "Aborted":
                break
            await asyncio.sleep(0.01)
        assert p.get(["BL:MOTORS", "state", "value"]) == "Aborted"
        devices["ZEBRA"].fail_at = None
        await p.post(["BL", "reset"])
        assert p.get(["BL", "state", "value"]) == "Ready"
        await p.post(["BL", "configure"], {"generator": spiral(),
                     "fileDir": str(tmp_path), "formatName": "again"})  # fmt: skip
        await p.post(["BL", "run"])
        assert p.get(["BL", "state", "value"]) == "Finished"
        with h5py.File(tmp_path / "again.nxs", "r") as f:
            assert f["/entry/uniqueid"][()].tolist() == list(range(1, 14))

    run(scenario)


def test_abort_writes_what_was_done(tmp_path):
    async def scenario():
        p, _ = await make(tmp_path)
        await p.post(["BL", "configure"], {"generator": spiral(11.3),
                     "fileDir": str(tmp_path), "formatName": "ab"})  # fmt: skip
        running = asyncio.ensure_future(p.post(["BL", "run"]))
        while p.get(["BL", "completedSteps", "value"]) < 5:
            await asyncio.sleep(0.005)
        await p.post(["BL", "abort"])
        with pytest.raises(MalcolmError):
            await running
        assert p.get(["BL", "state", "value"]) == "Aborted"
        with h5py.File(tmp_path / "ab.nxs", "r") as f:
            uid = f["/entry/uniqueid"][()]
            done = int((uid > 0).sum())
            assert 5 <= done < 402
            assert uid[:done].tolist() == list(range(1, done + 1))

    run(scenario)


def test_a_bad_file_template_is_refused_naming_it(tmp_path):
    async def scenario():
        p, devices = await make(tmp_path)
        for bad in ("scan.nxs%d", "a/%s.nxs"):
            with pytest.raises(MalcolmError, match="fileTemplate"):
                args = {"generator": spiral(), "fileTemplate": bad}
                await p.post(["BL", "configure"], {**args, "fileDir": str(tmp_path)})
            assert p.get(["BL", "state", "value"]) == "Ready"
        assert devices["DET"].got == {}

    run(scenario)


def test_a_child_already_in_fault_is_reset_by_configure(tmp_path):
    async def scenario():
        p, devices = await make(tmp_path)
        devices["DET"].fail_at = 0
        await p.post(["BL:DET", "configure"], {"generator": spiral()})
        with pytest.raises(MalcolmError):
            await p.post(["BL:DET", "run"])
        assert p.get(["BL:DET", "state", "value"]) == "Fault"
        devices["DET"].fail_at = None
        await p.post(["BL", "configure"], {"generator": spiral()})
        assert p.get(["BL", "state", "value"]) == "Armed"
        assert p.get(["BL:DET", "state", "value"]) == "Armed"
        await p.post(["BL", "run"])
        assert p.get(["BL", "state", "value"]) == "Finished"

    run(scenario)


class ShortestPoint(Part):
    """A detector's readout: a CompoundGenerator's duration under
    ``shortest`` comes back raised to it."""

    def __init__(self, shortest: float, delay: float) -> None:
        super().__init__("readout")
        self.shortest, self.delay = shortest, delay

    @RunnableDevice.Validate
    async def validate(self, task: Task, device: Any) -> dict[str, Any]:
        await asyncio.sleep(self.delay)  # 0: answers before the motion does
        generator = device.params["generator"]
        if float(generator["duration"]) < self.shortest:
            return {"generator": {**generator, "duration": self.shortest}}
        return {}


class SpeedLimit(Part):
    """A motion's speed check: points shorter than ``shortest`` are
    refused (the motors would be too fast)."""

    def __init__(self, shortest: float) -> None:
        super().__init__("speeds")
        self.shortest = shortest
        self.checked: list[float] = []

    @RunnableDevice.Validate
    async def validate(self, task: Task, device: Any) -> dict[str, Any]:
        duration = float(device.params["generator"]["duration"])
        self.checked.append(duration)
        if duration < self.shortest:
            raise BadValueError(f"{duration} s a point is too fast for the motors")
        return {}


@pytest.mark.parametrize("delay", [0.0, 0.02])
def test_the_motion_checks_the_duration_the_detector_raised(tmp_path, delay):
    """The detector raises a scan's duration to its shortest frame; the
    motion, which would refuse the duration asked for, checks the raised
    one: validate and configure give the raised duration, whichever child
    answers first."""

    async def scenario():
        process = Process()
        speeds = SpeedLimit(0.01)
        parts = {
            "DET": [FakeDevicePart("det", "{fmt}.data", "primary", 2),
                    ShortestPoint(0.01, delay)],
            "MOTORS": [FakeDevicePart("motors", "x.value", "position_value"),
                       speeds],
            "ZEBRA": [FakeDevicePart("zebra", "panda.INENC1.VAL", "monitor")],
        }  # fmt: skip
        add_beamline_manager(process, parts)
        await process.start()
        gen = spiral()  # 1 ms a point
        validated = await process.post(
            ["BL", "validate"], {"generator": gen, "axesToMove": ["x", "y"]}
        )
        assert validated["generator"]["duration"] == 0.01
        # the motion never refused: it checked the raised duration alone
        assert speeds.checked and set(speeds.checked) == {0.01}
        await process.post(["BL", "configure"], {"generator": gen})
        assert process.get(["BL", "state", "value"]) == "Armed"
        assert process.get(["BL:MOTORS", "state", "value"]) == "Armed"
        # a duration the detector keeps but the motion refuses still fails,
        # naming why
        speeds.shortest = 0.05
        with pytest.raises(MalcolmError, match="too fast for the motors"):
            await process.post(
                ["BL", "validate"], {"generator": gen, "axesToMove": ["x", "y"]}
            )
        await process.stop()

    run(scenario)

"""A manager's configure plans its scan once for its children and each child
validates once: the children take the points the manager built from the
very generator object it hands them (malcolm.scan.planned), and a child
whose validate() gave its arguments back unchanged inside the manager's
operation runs no Validate phase again when configured with them
(malcolm.controllers.validated). Anything else is read and validated as
before: a generator of equal content that is another object, a validate()
and configure() from a client, a child whose validate changed something."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from malcolm.beamline import add_beamline_manager
from malcolm.controllers.validated import Validated, same
from malcolm.core import BadValueError, MalcolmError, NumberMeta, Process
from malcolm.fsm import RunnableDevice
from malcolm.parts import Part, PartRegistrar
from malcolm.scan import gda, load, scan_points
from malcolm.scan.planned import PLANNED, planned_points, set_planned

from .scans import run
from .test_coordination import FakeDevicePart


class CheckPart(Part):
    """Counts its Validate phase's calls and what it was given; raises the
    scan's duration to ``least`` if given (as a detector's shortest frame);
    refuses a scan of more than ``most`` points."""

    def __init__(self, name: str, least: float | None = None) -> None:
        super().__init__(name)
        self.least = least
        self.most: int | None = None
        self.validated: list[dict[str, Any]] = []

    def setup(self, registrar: PartRegistrar) -> None:
        registrar.add_configure_arg("exposure", NumberMeta("float64"), 0.0)

    @RunnableDevice.Validate
    async def validate(self, task: Any, device: Any) -> dict[str, Any]:
        self.validated.append(dict(device.params))
        points = device.points
        if self.most is not None and points.size > self.most:
            raise BadValueError(f"{self.name}: {points.size} points is too many")
        gen = device.params["generator"]
        if self.least is not None and gen["duration"] < self.least:
            return {"generator": {**gen, "duration": self.least}}
        return {}


async def make(tmp_path: Path, least: float | None = None) -> tuple[Process, dict]:
    process = Process()
    checks = {}
    fakes = {
        "DET": FakeDevicePart("det", "{fmt}.data", "primary", 2),
        "MOTORS": FakeDevicePart("motors", "x.value", "position_value"),
        "ZEBRA": FakeDevicePart("zebra", "panda.INENC1.VAL", "monitor"),
    }
    for mri in fakes:
        checks[mri] = CheckPart("check", least if mri == "DET" else None)
    add_beamline_manager(
        process, {mri: [fake, checks[mri]] for mri, fake in fakes.items()}
    )
    await process.start()
    return process, checks


def grid(duration: float = 0.01) -> dict[str, Any]:
    return gda.compound(
        gda.line("y", 3, 0.0, 2.0),
        gda.line("x", 4, 0.0, 3.0, alternate=True),
        duration=duration,
    )


class Reads:
    """Counts how often a generator's content is read (its canonical JSON)."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.count = 0
        key = load._Built.key

        def counted(data: Any) -> str | None:
            self.count += 1
            return key(data)

        monkeypatch.setattr(load._Built, "key", staticmethod(counted))


def test_the_beamline_reads_its_generator_once(tmp_path, monkeypatch):
    async def scenario():
        p, _ = await make(tmp_path)
        reads = Reads(monkeypatch)
        await p.post(["BL", "configure"], {"generator": grid(),
                     "axesToMove": ["x", "y"], "fileDir": str(tmp_path)})  # fmt: skip
        assert p.get(["BL", "state", "value"]) == "Armed"
        for mri in ("DET", "MOTORS", "ZEBRA"):
            assert p.get([f"BL:{mri}", "state", "value"]) == "Armed"
            assert p.get([f"BL:{mri}", "totalSteps", "value"]) == 12
        # the beamline's own plan; its three children's validate and
        # configure (six plans) take the points it built from that object
        assert reads.count == 1

    run(scenario)


def test_each_child_validates_once_in_the_beamline_configure(tmp_path):
    async def scenario():
        p, checks = await make(tmp_path)
        await p.post(["BL", "configure"], {"generator": grid(),
                     "axesToMove": ["x", "y"], "fileDir": str(tmp_path)})  # fmt: skip
        for mri, check in checks.items():
            assert len(check.validated) == 1, mri
        # a validate of the beamline alone is its own operation: the
        # configure after it validates the children again, once each
        await p.post(["BL", "reset"])
        args = {"generator": grid(0.02), "axesToMove": ["x", "y"],
                "fileDir": str(tmp_path)}  # fmt: skip
        await p.post(["BL", "validate"], args)
        await p.post(["BL", "configure"], args)
        for mri, check in checks.items():
            assert len(check.validated) == 3, mri
            assert check.validated[-1]["generator"]["duration"] == 0.02

    run(scenario)


def test_a_child_whose_validate_changed_the_scan_validates_in_configure(tmp_path):
    async def scenario():
        p, checks = await make(tmp_path, least=0.05)
        await p.post(["BL", "configure"], {"generator": grid(0.01),
                     "axesToMove": ["x", "y"], "fileDir": str(tmp_path)})  # fmt: skip
        det, motors = checks["DET"], checks["MOTORS"]
        # the beamline's round 1: DET raised the duration (its own Validate
        # ran twice: the raise, then the raised scan unchanged) and MOTORS
        # checked the raised one; round 2: all gave the raised scan back
        # unchanged, so none validates again in its configure
        durations = [c["generator"]["duration"] for c in det.validated]
        assert durations == [0.01, 0.05, 0.05]
        assert [c["generator"]["duration"] for c in motors.validated] == [0.05] * 2
        assert p.get(["BL:DET", "state", "value"]) == "Armed"
        assert p.get(["BL", "state", "value"]) == "Armed"

    run(scenario)


def test_a_child_refusing_in_its_validate_refuses_the_beamline(tmp_path):
    async def scenario():
        p, checks = await make(tmp_path)
        checks["ZEBRA"].most = 5
        args = {"generator": grid(), "axesToMove": ["x", "y"],
                "fileDir": str(tmp_path)}  # fmt: skip
        with pytest.raises(MalcolmError, match="ZEBRA.*12 points is too many"):
            await p.post(["BL", "configure"], args)
        assert p.get(["BL", "state", "value"]) == "Ready"
        assert p.get(["BL:ZEBRA", "state", "value"]) == "Ready"

    run(scenario)


def test_a_client_validate_then_configure_validates_twice(tmp_path):
    async def scenario():
        p, checks = await make(tmp_path)
        args = {"generator": grid(), "axesToMove": ["x", "y"],
                "fileDir": str(tmp_path), "formatName": "m"}  # fmt: skip
        await p.post(["BL:MOTORS", "validate"], args)
        await p.post(["BL:MOTORS", "configure"], args)
        # no manager's operation around them: the configure validates too
        assert len(checks["MOTORS"].validated) == 2
        assert p.get(["BL:MOTORS", "state", "value"]) == "Armed"

    run(scenario)


def test_configure_with_other_arguments_than_validated_validates(tmp_path):
    async def scenario():
        p, checks = await make(tmp_path)
        ctrl = p.get_controller("BL:MOTORS")
        token = object()
        args = {"generator": grid(), "axesToMove": ["x", "y"],
                "fileDir": str(tmp_path), "formatName": "m"}  # fmt: skip
        # validated in an operation of a caller: a configure with another
        # exposure in that same operation validates again
        ctrl._validated = Validated(token, dict(args), {"check": {}})
        from malcolm.controllers.validated import CALLER

        reset = CALLER.set(token)
        try:
            await p.post(["BL:MOTORS", "configure"], {**args, "exposure": 0.5})
        finally:
            CALLER.reset(reset)
        assert len(checks["MOTORS"].validated) == 1
        assert checks["MOTORS"].validated[0]["exposure"] == 0.5

    run(scenario)


def test_same_arguments():
    gen = grid()
    assert same({"generator": gen, "a": [1, 2]}, {"generator": gen, "a": [1, 2]})
    assert same({"generator": gen}, {"generator": grid()})  # equal content
    assert not same({"generator": gen}, {"generator": grid(0.5)})
    assert not same({"a": 1}, {"a": 1, "b": 2})
    import numpy as np

    # arrays have no plain == answer: taken as different
    assert not same({"a": np.arange(3)}, {"a": np.arange(3)})
    arr = np.arange(3)
    assert same({"a": arr}, {"a": arr})


def test_planned_points_match_the_very_object_only():
    gen = grid()
    points = scan_points(gen)
    assert planned_points(gen) is None
    token = set_planned(gen, points)
    try:
        assert planned_points(gen) is points
        assert planned_points(grid()) is None  # equal content, another object
        # scan_points takes them (a copy sharing the dimensions)
        got = scan_points(gen)
        assert got is not points and got.content == points.content
        assert got.size == 12
    finally:
        PLANNED.reset(token)
    assert planned_points(gen) is None

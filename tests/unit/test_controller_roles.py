"""Controllers take their knowledge from the models (issue 7 item 14).

A renamed copy of the runnable model (every state and phase renamed, the
same roles and tags) runs a whole scan with the demo parts; the phases a
model declares on ``resume`` and ``fault`` run like any other move's.
"""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import Any

import pytest
import yaml

from malcolm.controllers.runnable import RunnableController
from malcolm.controllers.stateful import StatefulController
from malcolm.core import AbortedError, Process
from malcolm.fsm import Model, builtin_models_dir, load_model, model_class
from malcolm.parts import Part
from malcolm.parts.demo import (
    MotorMovePart,
    RunnableChildPart,
    SimDetectorPart,
    SimMotorPart,
)

from .scans import compound, run

CHAIN = ("stateful", "manager", "runnable_device")


def renamed(name: str) -> str:
    return f"Q{name}"


def _rename_list(value: Any) -> Any:
    if isinstance(value, list):
        return [renamed(v) for v in value]
    return renamed(value)


def write_renamed_models(directory: Path) -> Model:
    """Copies of the builtin runnable chain in ``directory`` with every state
    and phase renamed (``Ready`` -> ``QReady``), roles and tags kept, plus a
    phase on ``resume`` (role ``resume_run``) and on every ``fault`` move
    (role ``faulted``)."""
    for stem in CHAIN:
        data = yaml.safe_load((builtin_models_dir() / f"{stem}.yaml").read_text())
        data["name"] = renamed(data["name"])
        if "extends" in data:
            data["extends"] = f"q_{data['extends']}"
        if "initial" in data:
            data["initial"] = renamed(data["initial"])
        data["states"] = {renamed(k): v for k, v in data.get("states", {}).items()}
        data["phases"] = {renamed(k): v for k, v in data.get("phases", {}).items()}
        for t in data.get("transitions", []):
            t["source"] = _rename_list(t["source"])
            t["dest"] = renamed(t["dest"])
            if "phases" in t:
                t["phases"] = _rename_list(t["phases"])
        data["methods"] = {k: _rename_list(v) for k, v in data["methods"].items()}
        for rule in data.get("attributes", {}).values():
            rule["allowed"] = _rename_list(rule["allowed"])
        if stem == "runnable_device":
            data["phases"]["QResumeRun"] = {"role": "resume_run"}
            data["phases"]["QFaulted"] = {"role": "faulted"}
            for t in data["transitions"]:
                if t["trigger"] == "resume":
                    t["phases"] = ["QResumeRun"]
                if t["trigger"] == "fault":
                    t["phases"] = ["QFaulted"]
        (directory / f"q_{stem}.yaml").write_text(yaml.safe_dump(data))
    return load_model(directory / "q_runnable_device.yaml")


@pytest.fixture
def model(tmp_path: Path) -> Model:
    return write_renamed_models(tmp_path)


def test_the_copy_has_no_builtin_names_and_the_same_roles(model: Model) -> None:
    builtin = load_model("runnable_device")
    assert not set(model.states) & set(builtin.states)
    assert not set(model.phases) & set(builtin.phases)
    for name, info in builtin.states.items():
        assert model.state_for(info.role) == renamed(name)
        assert model.states[renamed(name)].tags == info.tags
    for name, info in builtin.phase_info.items():
        assert model.phase_for(info.role) == renamed(name)
        assert model.phase_info[renamed(name)].tags == info.tags


async def wait_for(predicate: Any, timeout: float = 10.0) -> None:
    async with asyncio.timeout(timeout):
        while not predicate():
            await asyncio.sleep(0.002)


def scan_process(model: Model) -> tuple[Process, list[str]]:
    """The demo's SCAN, two detectors and two motors, all on ``model``."""
    stateful = load_model(model.path.parent / "q_stateful.yaml")
    process = Process()
    for axis in ("X", "Y"):
        process.add_controller(
            StatefulController(f"MOTOR:{axis}", [SimMotorPart()], model=stateful)
        )
    for det in ("DET1", "DET2"):
        part = SimDetectorPart("detector", default_exposure=0.01)
        process.add_controller(RunnableController(det, [part], model=model))
    parts: list[Part] = [
        RunnableChildPart("DET1", "DET1"),
        RunnableChildPart("DET2", "DET2"),
        MotorMovePart("x", "MOTOR:X", "x"),
        MotorMovePart("y", "MOTOR:Y", "y"),
    ]
    process.add_controller(RunnableController("SCAN", parts, model=model))
    seen: list[str] = []
    process.subscribe(["SCAN", "state", "value"], seen.append, delta=False)
    return process, seen


def test_a_whole_scan_runs_on_the_renamed_model_with_the_demo_parts(model):
    role = model.state_for

    async def scenario() -> None:
        process, seen = scan_process(model)
        await process.start()
        scan = process.get_block("SCAN")
        det1 = process.get_block("DET1")
        generator = compound(("y", 3), ("x", 4), duration=0.02)

        await process.post(["SCAN", "configure"], {"generator": generator})
        assert scan.state.value == role("armed")
        assert det1.state.value == role("armed")

        # run, pause mid-run, seek back, resume to the end
        pending = asyncio.ensure_future(process.post(["SCAN", "run"]))
        await wait_for(lambda: scan.completedSteps.value >= 3)
        await process.post(["SCAN", "pause"])
        assert scan.state.value == role("paused")
        assert det1.state.value == role("paused")
        await process.put(["SCAN", "completedSteps"], 2)
        assert (scan.state.value, scan.completedSteps.value) == (role("paused"), 2)
        assert det1.completedSteps.value == 2
        await process.post(["SCAN", "resume"])
        await pending
        assert scan.state.value == role("finished")
        assert (scan.completedSteps.value, det1.completedSteps.value) == (12, 12)
        assert det1.state.value == role("finished")

        # again, aborted mid-run, then reset
        await process.post(["SCAN", "configure"], {"generator": generator})
        pending = asyncio.ensure_future(process.post(["SCAN", "run"]))
        await wait_for(lambda: scan.completedSteps.value >= 2)
        await process.post(["SCAN", "abort"])
        assert scan.state.value == role("aborted")
        assert det1.state.value == role("aborted")
        with pytest.raises(AbortedError):
            await pending
        await process.post(["SCAN", "reset"])
        assert scan.state.value == role("ready")
        assert det1.state.value == role("ready")
        assert scan.health.value == "OK"
        # every state the block showed is one of the renamed model's
        assert set(seen) <= set(model.states)
        await process.stop()

    run(scenario)


def recorder_class(model: Model) -> type[Part]:
    """A part that records the state each renamed resume/fault phase ran in."""
    phases = model_class(model)

    class Recorder(Part):
        def __init__(self, name: str) -> None:
            super().__init__(name)
            self.ran: list[tuple[str, str]] = []
            self.go = asyncio.Event()
            self.fail_run = False
            self.fail_faulted = False

        def setup(self, registrar: Any) -> None:
            self.controller = registrar.controller

        @phases.QResumeRun
        async def on_resume(self, task: Any, device: Any) -> None:
            self.ran.append(("QResumeRun", self.controller.current))

        @phases.QFaulted
        async def on_fault(self, task: Any, device: Any) -> None:
            self.ran.append(("QFaulted", self.controller.current))
            if self.fail_faulted:
                raise RuntimeError("the fault phase failed too")

        @phases.QRun
        async def on_run(self, task: Any, device: Any) -> None:
            for step in range(device.completedSteps, device.configuredSteps):
                await self.go.wait()
                if self.fail_run:
                    raise RuntimeError("lost the beam")
                task.report_progress(step + 1)

    return Recorder


def recorder_block(model: Model) -> tuple[Process, RunnableController, Any]:
    part = recorder_class(model)("rec")
    controller = RunnableController("BLOCK", [part], model=model)
    process = Process()
    process.add_controller(controller)
    return process, controller, part


def test_resume_runs_the_phases_the_model_puts_on_it(model):
    async def scenario() -> None:
        process, controller, part = recorder_block(model)
        await process.start()
        await process.post(["BLOCK", "configure"], {"generator": compound(("x", 4))})
        pending = asyncio.ensure_future(process.post(["BLOCK", "run"]))
        await wait_for(lambda: controller.current == "QRunning")
        await process.post(["BLOCK", "pause"])
        assert controller.current == "QPaused"
        await process.post(["BLOCK", "resume"])
        # the resume move ran its phase in the source state, then moved
        assert part.ran == [("QResumeRun", "QPaused")]
        part.go.set()
        await pending
        assert controller.current == "QFinished"

    run(scenario)


@pytest.mark.parametrize("fault_phase_fails", [False, True])
def test_a_fault_runs_the_phases_the_model_puts_on_it(model, fault_phase_fails):
    async def scenario() -> None:
        process, controller, part = recorder_block(model)
        part.fail_faulted = fault_phase_fails
        await process.start()
        await process.post(["BLOCK", "configure"], {"generator": compound(("x", 4))})
        part.fail_run = True
        part.go.set()
        with pytest.raises(Exception, match="lost the beam"):
            await process.post(["BLOCK", "run"])
        assert part.ran == [("QFaulted", "QRunning")]
        assert controller.current == "QFault"
        health = controller.health.value
        assert "lost the beam" in health
        # a failing fault phase does not stop the move; health says so too
        assert ("the fault phase failed too" in health) == fault_phase_fails

    run(scenario)


USER_PART = """
from malcolm.fsm import RunnableDevice
from malcolm.parts import Part


class Runner(Part):
    @RunnableDevice.Configure
    async def configure(self, task, device):
        raise AssertionError("check must not run it")
"""


def test_check_matches_a_user_parts_phases_by_role_as_serve_does(
    model, tmp_path, monkeypatch, capsys
):
    """`malcolm check` of a user part on a renamed model: its Configure is the
    model's QConfigure, as when the block is built."""
    from malcolm.cli import main
    from malcolm.config.build import build_definition

    (tmp_path / "roles_user_part.py").write_text(USER_PART)
    monkeypatch.syspath_prepend(str(tmp_path))
    definition = tmp_path / "d.yaml"
    definition.write_text(
        f"controller.RunnableController:\n    model: {model.path}\n"
        "parts.roles_user_part.Runner:\n    name: r\n"
    )
    assert main(["check", str(definition)]) == 0, capsys.readouterr()
    process = build_definition(definition, {}, "BOX")
    controller = process.get_controller("BOX")
    assert [h.part for h in controller.hooks["QConfigure"]] == ["r"]

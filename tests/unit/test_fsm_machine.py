"""Model queries, and the transitions.Machine built from a model."""

from __future__ import annotations

import pytest
import transitions

from malcolm.fsm import load_model


class Device:
    """A stand-in controller providing the runnable guards."""

    def __init__(self) -> None:
        self.complete = False
        self.paused = False
        self.asked: list[str] = []

    def scan_complete(self) -> bool:
        self.asked.append("scan_complete")
        return self.complete

    def is_paused(self) -> bool:
        self.asked.append("is_paused")
        return self.paused


@pytest.fixture
def device() -> Device:
    device = Device()
    load_model("runnable_device").build_machine(device)
    return device


def test_machine_options() -> None:
    device = Device()
    machine = load_model("runnable_device").build_machine(device)
    assert isinstance(machine, transitions.Machine)
    assert device.state == "Disabled"
    assert not hasattr(device, "to_Ready")  # auto_transitions=False
    assert set(machine.states) == set(load_model("runnable_device").states)
    assert not machine.send_event


def test_kwargs_override_defaults() -> None:
    device = Device()
    load_model("runnable_device").build_machine(device, initial="Armed")
    assert device.state == "Armed"


def test_a_scan_of_two_runs(device: Device) -> None:
    device.init()
    device.done()
    assert device.state == "Ready"
    device.configure()
    assert device.state == "Configuring"
    device.done()
    assert device.state == "Armed"
    device.run()
    device.done()
    assert device.state == "PostRun"
    device.done()  # not complete: back to Armed for the next run
    assert device.state == "Armed"
    device.run()
    device.done()
    device.complete = True
    device.done()
    assert device.state == "Finished"


def test_seek_guards_are_tried_in_order(device: Device) -> None:
    device.init()
    device.done()
    device.configure()
    device.done()
    device.run()
    device.pause()
    assert device.state == "Seeking"
    device.paused = True
    device.complete = True
    device.asked.clear()
    device.done()
    assert device.state == "Paused"  # is_paused is listed first
    assert device.asked == ["is_paused"]
    device.resume()
    assert device.state == "Running"
    device.pause()
    device.paused = False
    device.done()
    assert device.state == "Finished"


def test_invalid_triggers_raise(device: Device) -> None:
    with pytest.raises(transitions.MachineError):
        device.run()
    assert device.state == "Disabled"


def test_abort_and_reset(device: Device) -> None:
    device.init()
    device.done()
    device.abort()
    assert device.state == "Aborting"
    device.done()
    assert device.state == "Aborted"
    device.reset()
    assert device.state == "Resetting"
    device.fault()
    assert device.state == "Fault"
    device.disable()
    device.done()
    assert device.state == "Disabled"


def test_queries() -> None:
    model = load_model("runnable_device")
    assert model.guards() == {"scan_complete", "is_paused"}
    assert model.busy_states() == {
        "Resetting",
        "Disabling",
        "Saving",
        "Loading",
        "Configuring",
        "Running",
        "Seeking",
        "PostRun",
        "Aborting",
    }
    assert [t.dest for t in model.transitions_for("done", "Seeking")] == [
        "Paused",
        "Finished",
        "Armed",
    ]
    assert model.transitions_for("run", "Ready") == []
    assert model.triggers_from("Paused") == {
        "pause",
        "seek",
        "resume",
        "abort",
        "fault",
        "disable",
    }
    assert model.triggers_from("Disabled") == {"init", "reset"}
    assert model.moves()["Disabled"] == {"Resetting"}
    assert model.allows("configure", "Finished")
    assert not model.allows("configure", "Armed")
    assert model.allows("greet", "Fault")  # calls not in the table: any state
    assert model.put_allowed("completedSteps", "Paused")
    assert not model.put_allowed("completedSteps", "Running")
    assert model.put_allowed("exposure", "Running")  # not in the table
    assert model.attributes["completedSteps"].trigger == "seek"
    assert model.attributes["design"].trigger == "load"

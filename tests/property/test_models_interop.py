"""The builtin models move and allow calls exactly as GDA expects
(shared/design/interop.md section 1)."""

from __future__ import annotations

import pytest

from malcolm.fsm import load_model

# interop.md §1, "Allowed moves in the reference implementation"
MOVES = {
    "Ready": {"Saving", "Loading", "Configuring", "Aborting", "Fault", "Disabling"},
    "Resetting": {"Ready", "Fault", "Disabling"},
    "Saving": {"Ready", "Fault", "Disabling"},
    "Loading": {"Ready", "Fault", "Disabling"},
    "Configuring": {"Armed", "Aborting", "Fault", "Disabling"},
    "Armed": {"Resetting", "Running", "Seeking", "Aborting", "Fault", "Disabling"},
    "Running": {"Seeking", "PostRun", "Aborting", "Fault", "Disabling"},
    "Seeking": {"Armed", "Finished", "Paused", "Aborting", "Fault", "Disabling"},
    "PostRun": {"Armed", "Seeking", "Finished", "Aborting", "Fault", "Disabling"},
    "Finished": {
        "Resetting",
        "Configuring",
        "Seeking",
        "Aborting",
        "Fault",
        "Disabling",
    },
    "Paused": {"Running", "Seeking", "Aborting", "Fault", "Disabling"},
    "Aborting": {"Aborted", "Fault", "Disabling"},
    "Aborted": {"Resetting", "Fault", "Disabling"},
    "Fault": {"Resetting", "Disabling"},
    "Disabling": {"Fault", "Disabled"},
    "Disabled": {"Resetting"},
}

# interop.md §1, "Which calls are allowed where"
CALLS = {
    "configure": {"Ready", "Finished"},
    "run": {"Armed"},
    "abort": {
        "Ready",
        "Configuring",
        "Armed",
        "Running",
        "PostRun",
        "Paused",
        "Seeking",
        "Finished",
    },
    "pause": {"Armed", "Paused", "Running", "Finished"},
    "resume": {"Paused"},
    "reset": {"Fault", "Disabled", "Aborted", "Armed", "Finished"},
    "save": {"Ready"},
}
PUTS = {
    "completedSteps": ({"Paused", "Armed"}, "seek"),
    "design": ({"Ready"}, "load"),
    "layout": ({"Ready"}, None),
    "exports": ({"Ready"}, None),
    # beyond the interop table: the editor's follower table
    "followers": ({"Ready"}, None),
    # and its fixed table
    "fixed": ({"Ready"}, None),
}
# Beyond the interop table: validate never moves; disable wherever it can;
# the editor's calls (load, set_visible, set_position) only in Ready.
EXTRA_CALLS = {
    "validate": {"Ready", "Finished", "Armed"},
    "load": {"Ready"},
    "set_visible": {"Ready"},
    "set_position": {"Ready"},
    "disable": {s for s, dests in MOVES.items() if "Disabling" in dests},
}

STATEFUL = {"Resetting", "Ready", "Fault", "Disabling", "Disabled"}
MANAGER = STATEFUL | {"Saving", "Loading"}
RUNNABLE = ["runnable_device", "area_detector_runnable_device"]


def _restricted(states: set[str]) -> dict[str, set[str]]:
    return {s: MOVES[s] & states for s in states}


@pytest.mark.parametrize("stem", RUNNABLE)
def test_runnable_moves_are_the_interop_table(stem: str) -> None:
    assert load_model(stem).moves() == MOVES


@pytest.mark.parametrize("stem", RUNNABLE)
def test_runnable_calls_are_the_interop_table(stem: str) -> None:
    model = load_model(stem)
    assert model.methods == {
        name: frozenset(states) for name, states in (CALLS | EXTRA_CALLS).items()
    }
    assert {
        name: (set(rule.allowed), rule.trigger)
        for name, rule in model.attributes.items()
    } == PUTS
    for state in MOVES:
        for call, allowed in CALLS.items():
            assert model.allows(call, state) == (state in allowed), (call, state)
        for name, (allowed, _) in PUTS.items():
            assert model.put_allowed(name, state) == (state in allowed), (name, state)


def test_stateful_and_manager_use_their_subset_of_the_table() -> None:
    assert load_model("stateful").moves() == _restricted(STATEFUL)
    assert load_model("manager").moves() == _restricted(MANAGER)


@pytest.mark.parametrize("stem", ["stateful", "manager", *RUNNABLE])
def test_starts_disabled_and_init_resets_to_ready(stem: str) -> None:
    model = load_model(stem)
    assert model.initial == "Disabled"
    (init,) = model.transitions_for("init", "Disabled")
    assert init.dest == "Resetting"
    (done,) = model.transitions_for("done", "Resetting")
    assert done.dest == "Ready"


def test_runnable_state_names_are_the_ones_gda_maps() -> None:
    assert list(load_model("runnable_device").states) == [
        "Resetting",
        "Ready",
        "Fault",
        "Disabling",
        "Disabled",
        "Saving",
        "Loading",
        "Configuring",
        "Armed",
        "Running",
        "Seeking",
        "PostRun",
        "Finished",
        "Paused",
        "Aborting",
        "Aborted",
    ]

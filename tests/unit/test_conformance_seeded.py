"""Each seeded defect of issue 7 item 15's kinds (tests/seeded/) makes
`pytest tests/property` fail within 60 s, naming the defect. The suite runs
in a subprocess with the seed as a plugin and -x: its cheapest, most
certain checks run first (tests/property/conftest.py), so it stops at the
first one that sees the defect."""

from __future__ import annotations

import pytest

from tests.seeded import run_pytest

#: seed -> (the test that must fail, words its report must contain)
SEEDS = {
    "phase_fired_by_nothing": (
        "test_models.py::test_model_follows_design_rules",
        ["runnable_device.yaml:", "transition seek PostRun->Seeking", "Pause",
         "nothing fires it"],
    ),
    "forgotten_phase": (
        "test_phase_table.py::test_model_runs_the_phases_of_the_table",
        ["runnable_device.yaml:", "transition done Seeking->Armed runs phases []",
         "phase_table.yaml:", "says [Seek]"],
    ),
    "ad_phase_order": (
        "test_phase_table.py::test_model_runs_the_phases_of_the_table",
        ["transition done Running->PostRun runs phases [PreRun, PreRunDriverStart,"
         " PreRunPluginStart", "says [PreRun, PreRunPluginStart, PreRunDriverStart",
         "area_detector_runnable_device.yaml:"],
    ),
    "runner_returns_early": (
        "test_phases_live.py::test_live_controller_runs_the_phases",
        ["while part 'slow' was still running its Init hook",
         "a phase must end only when all its hooks have returned"],
    ),
    "controller_skips_phase": (
        "test_phases_live.py::test_live_controller_runs_the_phases",
        ["transition done Seeking->Armed", "runnable_device.yaml:",
         "should run [Seek], but the block ran []"],
    ),
    "progress_fastest": (
        "test_phases_live.py::test_live_controller_runs_the_phases",
        ["after run(): completedSteps became 1 while part",
         "progress must be the slowest working part's"],
    ),
    "fixed_not_restored": (
        "test_designs_live.py::test_designs_hold_and_are_restored",
        ["designs/BL18I_Z1/example.yaml:", "after reset, PCOMP2.WIDTH is 31,"
         " but the design says it is fixed at 32"],
    ),
    "health_without_values": (
        "test_designs_live.py::test_designs_hold_and_are_restored",
        ["designs/BL18I_Z1/example.yaml:", "must name PCOMP2.WIDTH, the expected"
         " value 32 and the actual value 31"],
    ),
}  # fmt: skip


@pytest.mark.parametrize("seed", sorted(SEEDS))
def test_seeded_defect_fails_the_conformance_suite(seed: str) -> None:
    test, words = SEEDS[seed]
    done = run_pytest("tests/property", "-x", "-q", "-p", f"tests.seeded.seed_{seed}")
    report = done.stdout + done.stderr
    assert done.returncode == 1, report
    failed = [line for line in done.stdout.splitlines() if line.startswith("FAILED")]
    assert len(failed) == 1 and f"tests/property/{test}" in failed[0], report
    for word in words:
        assert word in done.stdout, f"{word!r} not in:\n{report}"

"""--malcolm-models and --malcolm-designs, from either command line
(`pytest tests ...` and `pytest tests/property ...`), give a user's models
and designs the conformance tests, and failures name the file and line."""

from __future__ import annotations

from tests.seeded import run_pytest

LAMP = "tests/property/fixtures/user/lamp.yaml"
BROKEN = "tests/property/fixtures/user/broken_lamp.yaml"
DESIGNS = "tests/property/fixtures/designs/process.yaml"


def test_both_options_from_tests_collect_the_users_files() -> None:
    done = run_pytest(
        "tests", "--co", "-q", "--malcolm-models", LAMP, "--malcolm-designs", DESIGNS
    )
    assert done.returncode == 0, done.stdout + done.stderr
    ids = done.stdout.splitlines()
    for test in (
        "test_models.py::test_model_follows_design_rules",
        "test_model_walks.py::test_random_walk_follows_the_model",
        "test_phases_live.py::test_live_controller_runs_the_phases",
        "test_controller_machines.py::test_controller_machine",
    ):
        assert f"tests/property/{test}[{LAMP}]" in ids, test
    for test in (
        "test_designs_live.py::test_designs_hold_and_are_restored",
        "test_manager_machine.py::test_editor_machine_on_designs",
    ):
        assert f"tests/property/{test}[{DESIGNS}]" in ids, test


def passed(stdout: str) -> set[str]:
    """The ids ``pytest -v`` reports PASSED."""
    return {
        line.split(" PASSED")[0] for line in stdout.splitlines() if " PASSED" in line
    }


def test_a_users_model_gets_the_live_checks_and_passes() -> None:
    done = run_pytest("tests", "-x", "-v", "-k", "lamp", "--malcolm-models", LAMP)
    assert done.returncode == 0, done.stdout + done.stderr
    for test in (
        "test_models.py::test_model_follows_design_rules",
        "test_model_walks.py::test_random_walk_follows_the_model",
        "test_phases_live.py::test_live_controller_runs_the_phases",
        "test_phases_live.py::test_the_script_takes_every_transition_with_phases",
        "test_controller_machines.py::test_controller_machine",
    ):
        assert f"tests/property/{test}[{LAMP}]" in passed(done.stdout), test


def test_a_users_broken_model_fails_naming_file_line_and_state() -> None:
    done = run_pytest(
        "tests/property", "-q", "-k", "broken_lamp", "--malcolm-models", BROKEN
    )
    assert done.returncode == 1, done.stdout + done.stderr
    assert f"{BROKEN}:9: state Glowing has no move to Blown" in done.stdout


def test_a_users_designs_get_the_live_checks() -> None:
    done = run_pytest(
        "tests/property", "-x", "-v", "-k", "fixtures", "--malcolm-designs", DESIGNS
    )
    assert done.returncode == 0, done.stdout + done.stderr
    for test in (
        "test_designs_live.py::test_designs_hold_and_are_restored",
        "test_manager_machine.py::test_editor_machine_on_designs",
    ):
        assert f"tests/property/{test}[{DESIGNS}]" in passed(done.stdout), test


def test_a_users_design_fault_names_the_design_row() -> None:
    done = run_pytest(
        "tests/property", "-x", "-q", "-k", "fixtures", "--malcolm-designs", DESIGNS,
        "-p", "tests.seeded.seed_health_without_values",
    )  # fmt: skip
    assert done.returncode == 1, done.stdout + done.stderr
    row = "tests/property/fixtures/designs/designs/TEST_ZEBRA/gates.yaml:19:"
    assert f"{row} health 'TEST:ZEBRA: PCOMP1.WIDTH has drifted' must name" in (
        done.stdout
    ), done.stdout


def test_a_path_that_is_not_there_is_a_usage_error() -> None:
    done = run_pytest("tests/property", "--malcolm-models", "no/such.yaml",
                      "--malcolm-designs", "no/process.yaml")  # fmt: skip
    assert done.returncode == 4, done.stdout + done.stderr
    assert "--malcolm-models no/such.yaml: no such file or directory" in done.stderr
    assert "--malcolm-designs no/process.yaml: no such process file" in done.stderr

"""Shared test set-up: no test writes designs into the repository."""

import pytest


@pytest.fixture(autouse=True)
def _designs_in_tmp(tmp_path, monkeypatch):
    monkeypatch.setenv("MALCOLM_DESIGNS_DIR", str(tmp_path / "designs"))


# ---- design conformance options (docs/conformance.md) -----------------------
# Here, not in tests/property/conftest.py, so that both `pytest tests ...`
# and `pytest tests/property ...` accept them.


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("malcolm", "malcolm design conformance (tests/property)")
    group.addoption(
        "--malcolm-models",
        action="append",
        default=[],
        metavar="PATH",
        help="also check these model files, or every *.yaml in these directories:"
        " design rules, and live controllers built from them (repeatable)",
    )
    group.addoption(
        "--malcolm-designs",
        action="append",
        default=[],
        metavar="PROCESS",
        help="also check the designs of every manager this process file builds"
        " (its saved designs and templates), on live managers (repeatable)",
    )


def pytest_configure(config: pytest.Config) -> None:
    from malcolm.conformance.options import read_options

    read_options(config)

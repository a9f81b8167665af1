"""Shared test set-up: no test writes designs into the repository."""

import gc
import logging
import os
import warnings

import pytest

from malcolm.core import enable_loop_guard
from malcolm.core.threads import guard_trips

# ca.* attributes of blocks built in tests talk to the in-memory soft backend
# unless a test chooses pyepics itself (tests/system/ca: a real IOC)
os.environ.setdefault("MALCOLM_CA_BACKEND", "soft")


@pytest.fixture(autouse=True)
def _designs_in_tmp(tmp_path, monkeypatch):
    monkeypatch.setenv("MALCOLM_DESIGNS_DIR", str(tmp_path / "designs"))


# ---- the loop guard (docs/channels.md): block state changed off its process's
# loop thread raises in every test
enable_loop_guard()


@pytest.fixture(autouse=True)
def _loop_guard_not_tripped():
    """Fail a test in which the guard raised, even where the error was
    swallowed (a subscriber callback, a thread nobody joined)."""
    guard_trips.clear()
    yield
    tripped = list(guard_trips)
    guard_trips.clear()
    assert not tripped, f"the loop guard tripped: {tripped}"


# ---- dropped futures: "Task exception was never retrieved" (asyncio's log) and
# "coroutine ... was never awaited" (a RuntimeWarning: an error by pyproject's
# filterwarnings) fail the test that leaked them, or else the session
class _LeakLog(logging.Handler):
    def __init__(self):
        super().__init__(logging.ERROR)
        self.leaks = []

    def emit(self, record):
        text = record.getMessage()
        if "never retrieved" in text or "never awaited" in text:
            self.leaks.append(text)


_leaks = _LeakLog()
logging.getLogger("asyncio").addHandler(_leaks)


@pytest.fixture(autouse=True)
def _no_dropped_futures():
    before = len(_leaks.leaks)
    yield
    gc.collect(1)  # cheap; what survived longer is found at the session's end
    leaked = _leaks.leaks[before:]
    assert not leaked, f"futures were dropped: {leaked}"


@pytest.fixture(autouse=True, scope="session")
def _no_dropped_futures_at_the_end():
    yield
    before = len(_leaks.leaks)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        gc.collect()
    leaked = _leaks.leaks[before:] + [
        str(w.message) for w in caught if "never awaited" in str(w.message)
    ]
    assert not leaked, f"futures were dropped: {leaked}"


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

"""Shared test set-up: no test writes designs into the repository."""

import pytest


@pytest.fixture(autouse=True)
def _designs_in_tmp(tmp_path, monkeypatch):
    monkeypatch.setenv("MALCOLM_DESIGNS_DIR", str(tmp_path / "designs"))


# ---- the loop guard (docs/channels.md): block state changed off its process's
# loop thread raises in every test
def pytest_configure(config):
    from malcolm.core import enable_loop_guard

    enable_loop_guard()


@pytest.fixture(autouse=True)
def _loop_guard_not_tripped():
    """Fail a test in which the guard raised, even where the error was
    swallowed (a subscriber callback, a thread nobody joined)."""
    from malcolm.core.threads import guard_trips

    guard_trips.clear()
    yield
    tripped = list(guard_trips)
    guard_trips.clear()
    assert not tripped, f"the loop guard tripped: {tripped}"

"""Shared test set-up: no test writes designs into the repository."""

import pytest


@pytest.fixture(autouse=True)
def _designs_in_tmp(tmp_path, monkeypatch):
    monkeypatch.setenv("MALCOLM_DESIGNS_DIR", str(tmp_path / "designs"))

"""MALCOLM_MODELS_DIR points the builtin models at edited copies (how the
seeded-defect meta-tests seed defects into them)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from malcolm.fsm import builtin_models_dir, load_model, model_names


def test_models_dir_override(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    real = builtin_models_dir()
    copy = tmp_path / "models"
    shutil.copytree(real, copy)
    stateful = copy / "stateful.yaml"
    stateful.write_text(stateful.read_text().replace("name: Stateful", "name: Edited"))
    monkeypatch.setenv("MALCOLM_MODELS_DIR", str(copy))
    assert builtin_models_dir() == copy
    assert load_model("stateful").name == "Edited"
    assert load_model("manager").parent.name == "Edited"  # extends finds the copy
    assert model_names() == sorted(p.stem for p in real.glob("*.yaml"))
    monkeypatch.delenv("MALCOLM_MODELS_DIR")
    assert builtin_models_dir() == real

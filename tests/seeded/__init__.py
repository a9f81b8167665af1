"""Seeded defects: each module is a pytest plugin that plants one defect of
issue 7 item 15's kinds, for ``pytest tests/property -p tests.seeded.<name>``
to catch (tests/unit/test_conformance_seeded.py runs each and checks that
the conformance suite fails, naming the defect, within 60 s).

Model seeds edit a copy of the builtin models (``MALCOLM_MODELS_DIR``) when
the plugin is imported, before anything loads a model. Code seeds replace a
function everywhere it is bound (the seams listed in docs/conformance.md).
"""

from __future__ import annotations

import atexit
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[2]
LIMIT = 60.0  # seconds: issue 7 item 15's bound on catching a seeded defect


def seed_models(edits: dict[str, tuple[str, str]]) -> Path:
    """Copy the builtin models, apply ``{file: (old text, new text)}``, and
    point MALCOLM_MODELS_DIR at the copy. A seed whose text is no longer in
    the model fails loudly rather than plant nothing."""
    copy = Path(tempfile.mkdtemp(prefix="malcolm-seeded-models-"))
    atexit.register(shutil.rmtree, copy, True)
    shutil.copytree(ROOT / "models", copy, dirs_exist_ok=True)
    for name, (old, new) in edits.items():
        path = copy / name
        text = path.read_text()
        if old not in text:
            raise RuntimeError(f"seed no longer applies: {old!r} is not in {name}")
        path.write_text(text.replace(old, new, 1))
    os.environ["MALCOLM_MODELS_DIR"] = str(copy)
    return copy


def replace_everywhere(original: Any, replacement: Any) -> int:
    """Bind ``replacement`` wherever a loaded malcolm module or class binds
    ``original``; returns how many places (a seed that finds none fails)."""
    import malcolm.controllers.manager  # noqa: F401  (load what binds the seams)
    import malcolm.controllers.runnable  # noqa: F401
    import malcolm.controllers.stateful  # noqa: F401
    import malcolm.editor.runtime  # noqa: F401

    count = 0
    for name, module in list(sys.modules.items()):
        if not name.startswith("malcolm") or module is None:
            continue
        for owner in [module, *vars(module).values()]:
            if not (owner is module or isinstance(owner, type)):
                continue
            for attr, value in list(vars(owner).items()):
                if value is original:
                    setattr(owner, attr, replacement)
                    count += 1
    if count == 0:
        raise RuntimeError(f"seed found nowhere to plant {original!r}")
    return count


def run_pytest(*args: str) -> subprocess.CompletedProcess[str]:
    """``python -m pytest ARGS`` from the top of the tree, within LIMIT."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    for name in ("MALCOLM_MODELS_DIR", "MALCOLM_DESIGNS_DIR", "PYTEST_ADDOPTS"):
        env.pop(name, None)
    command = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", *args]
    try:
        return subprocess.run(
            command, cwd=ROOT, env=env, capture_output=True, text=True, timeout=LIMIT
        )
    except subprocess.TimeoutExpired as e:
        pytest.fail(f"{' '.join(command)} did not end within {LIMIT} s:\n{e.stdout}")

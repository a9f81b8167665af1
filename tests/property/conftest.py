"""Model conformance tests run over the builtin models and any given with
``--malcolm-models PATH`` (a model file or a directory of them; repeatable)."""

from __future__ import annotations

from pathlib import Path

import pytest

from malcolm.fsm import builtin_models_dir


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--malcolm-models",
        action="append",
        default=[],
        metavar="PATH",
        help="also check these model files, or every *.yaml in these directories, "
        "against the design rules (repeatable)",
    )


def model_paths(config: pytest.Config) -> list[Path]:
    """The builtin models, then those given on the command line."""
    paths = sorted(builtin_models_dir().glob("*.yaml"))
    for given in config.getoption("malcolm_models", default=None) or []:
        path = Path(given)
        if path.is_dir():
            paths += sorted(path.glob("*.yaml"))
        else:
            paths.append(path)
    return paths


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    if "model_path" in metafunc.fixturenames:
        paths = model_paths(metafunc.config)
        metafunc.parametrize("model_path", paths, ids=[str(p) for p in paths])

"""Design conformance (docs/conformance.md): the tests here run over the
builtin models and designs, and over those given with ``--malcolm-models
PATH`` (model files, or directories of them) and ``--malcolm-designs
PROCESS`` (process files: their managers' designs); both options are
defined in tests/conftest.py, so `pytest tests` takes them too.

Fixtures, by parameter name:

- ``model_path``: every model file, builtin first;
- ``design_source``: the builtin Zebra2 process with the repository's
  designs, then every ``--malcolm-designs`` process file.

Tests run cheapest and most certain first (static checks, then the
scripted live checks, then the hypothesis machines, then the fuzzers), so
that ``-x`` stops at a defect within seconds.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from malcolm.conformance.options import DesignSource, options_of
from malcolm.fsm import builtin_models_dir

ROOT = Path(__file__).resolve().parents[2]
BUILTIN_DESIGNS = DesignSource(
    ROOT / "malcolm/blocks/zebra2/process.yaml", ROOT / "designs", ()
)
#: test modules in the order they run (others after these)
ORDER = (
    "test_models.py",
    "test_models_defects.py",
    "test_models_interop.py",
    "test_phase_table.py",
    "test_phases_live.py",
    "test_designs_live.py",
    "test_model_walks.py",
    "test_controller_machines.py",
    "test_manager_machine.py",
    "test_check_fuzz.py",
)


def model_paths(config: pytest.Config) -> list[Path]:
    """The builtin models, then those given on the command line."""
    return sorted(builtin_models_dir().glob("*.yaml")) + options_of(config).models


def design_sources(config: pytest.Config) -> list[DesignSource]:
    return [BUILTIN_DESIGNS, *options_of(config).designs]


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    if "model_path" in metafunc.fixturenames:
        paths = model_paths(metafunc.config)
        metafunc.parametrize("model_path", paths, ids=[str(p) for p in paths])
    if "design_source" in metafunc.fixturenames:
        sources = design_sources(metafunc.config)
        metafunc.parametrize(
            "design_source", sources, ids=[str(s.process) for s in sources]
        )


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Put this directory's tests in ORDER, leaving other tests where they are."""
    here = Path(__file__).parent
    slots = [i for i, item in enumerate(items) if item.path.parent == here]
    ours = [items[i] for i in slots]

    def rank(item: pytest.Item) -> int:
        name = item.path.name
        return ORDER.index(name) if name in ORDER else len(ORDER)

    for slot, item in zip(slots, sorted(ours, key=rank)):
        items[slot] = item

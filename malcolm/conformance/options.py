"""The ``--malcolm-models`` and ``--malcolm-designs`` options of the
conformance tests: what they name, checked before any test runs."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import pytest


@dataclass(frozen=True)
class DesignSource:
    """A process file whose managers' designs are checked."""

    process: Path
    #: where its managers keep designs unless their definition says
    designs_dir: Path
    search_path: tuple[str, ...] = ()


@dataclass
class Options:
    models: list[Path] = field(default_factory=list)
    designs: list[DesignSource] = field(default_factory=list)


def model_files(given: list[str]) -> tuple[list[Path], list[str]]:
    """The model files named (a directory: its ``*.yaml``), and problems."""
    found: list[Path] = []
    problems = []
    for text in given:
        path = Path(text)
        if path.is_dir():
            files = sorted(path.glob("*.yaml"))
            if not files:
                problems.append(f"--malcolm-models {text}: no *.yaml files in it")
            found += files
        elif path.is_file():
            found.append(path)
        else:
            problems.append(f"--malcolm-models {text}: no such file or directory")
    return found, problems


def design_sources(given: list[str]) -> tuple[list[DesignSource], list[str]]:
    """The process files named, each with where its designs are, and problems.

    A manager's designs are where ``malcolm serve`` would look for them from
    here: its ``designs_dir``, else ``$MALCOLM_DESIGNS_DIR``, else
    ``./designs`` (read now: the tests point the variable elsewhere).
    """
    base = Path(os.environ.get("MALCOLM_DESIGNS_DIR") or Path.cwd() / "designs")
    found = []
    problems = []
    for text in given:
        from malcolm.checker import default_search_path

        path = Path(text)
        if not path.is_file():
            problems.append(f"--malcolm-designs {text}: no such process file")
            continue
        search = tuple(default_search_path(path))
        found.append(DesignSource(path, base.resolve(), search))
    return found, problems


def read_options(config: pytest.Config) -> Options:
    """Parse both options once; a name that is not there stops pytest."""
    models, problems = model_files(config.getoption("malcolm_models", []) or [])
    designs, more = design_sources(config.getoption("malcolm_designs", []) or [])
    if problems + more:
        raise pytest.UsageError("\n".join(problems + more))
    options = Options(models, designs)
    config.stash[_KEY] = options
    return options


def options_of(config: pytest.Config) -> Options:
    """The options :func:`read_options` parsed (parsing them if need be)."""
    found = config.stash.get(_KEY, None)
    return found if found is not None else read_options(config)


_KEY = pytest.StashKey[Options]()

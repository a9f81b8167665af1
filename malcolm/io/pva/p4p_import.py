"""Import p4p without importing setuptools (half of p4p's import time).

p4p finds its EPICS libraries with ``epicscorelibs.path`` and
``pvxslibs.path``, which use two functions of ``setuptools_dso.runtime``;
but ``setuptools_dso/__init__.py`` first imports setuptools' build machinery
(about 0.3 s on a loaded machine), needed only to build packages. While p4p
is imported, :func:`import_p4p` puts a bare ``setuptools_dso`` package in
``sys.modules`` holding just those two functions, then takes it out again:
a later ``import setuptools_dso`` loads the real one (reusing the same
``runtime`` module). Anything unexpected falls back to a plain import.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
import types

__all__ = ["import_p4p"]


def import_p4p() -> None:
    """Import p4p (once), without setuptools when it can."""
    if "p4p" in sys.modules:
        return
    stub = None
    try:
        if "setuptools_dso" not in sys.modules:
            spec = importlib.util.find_spec("setuptools_dso")
            if spec is not None and spec.submodule_search_locations:
                stub = types.ModuleType("setuptools_dso")
                stub.__path__ = list(spec.submodule_search_locations)
                sys.modules["setuptools_dso"] = stub
                runtime = importlib.import_module("setuptools_dso.runtime")
                stub.dylink_prepare_dso = runtime.dylink_prepare_dso  # type: ignore[attr-defined]
                stub.find_dso = runtime.find_dso  # type: ignore[attr-defined]
        importlib.import_module("p4p")
    except Exception:
        if stub is not None and sys.modules.get("setuptools_dso") is stub:
            del sys.modules["setuptools_dso"]
            stub = None
        importlib.import_module("p4p")  # the ordinary way (its errors are real)
    finally:
        if stub is not None and sys.modules.get("setuptools_dso") is stub:
            del sys.modules["setuptools_dso"]

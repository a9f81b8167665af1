"""Check one file of each kind, as deeply as can be done without starting
anything or running a user's code.

- a **definition** is loaded, every section kind looked up, then expanded
  with placeholder values and checked by
  :func:`malcolm.config.build.check_block`;
- a **process** file is loaded with its includes and definitions, expanded,
  and checked by :func:`malcolm.config.build.check_process`;
- a **design** is read by :func:`malcolm.parts.design.load_design`;
- a **model** is loaded and checked against the guards of the controller it
  names.

``check_block``/``check_process`` import every class a section names and
inspect it (keywords, annotations, hook functions, phase timeouts); only
malcolm's own controllers and parts are made, never started.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path

from malcolm import yamlio

from .files import default_search_path, expand_files
from .findings import CheckResult, Finding, findings_of
from .kinds import detect_kind

__all__ = ["check_file", "check_files"]

#: Placeholder values of each type, to expand a definition whose required
#: parameters have no defaults.
_PLACEHOLDERS = {"String": "CHECK", "Int": 1, "Float": 1.0, "Boolean": False}


def check_file(
    path: str | Path, search_path: Sequence[str] = (), kind: str | None = None
) -> CheckResult:
    """Check one file; never raises (an unexpected error is a finding)."""
    file = str(path)
    result = CheckResult(file, None)
    try:
        _check(Path(path), file, search_path, kind, result)
    except Exception as e:  # the promise: no traceback, ever
        result.problems.append(
            Finding(file, None, f"internal error: {type(e).__name__}: {e}")
        )
    seen: set[str] = set()
    unique = []
    for p in result.problems:
        if str(p) not in seen:
            seen.add(str(p))
            unique.append(p)
    result.problems = unique
    return result


def check_files(
    paths: Iterable[str | Path],
    search_path: Sequence[str] = (),
    kind: str | None = None,
) -> list[CheckResult]:
    """:func:`check_file` of each path."""
    return [check_file(p, search_path, kind) for p in paths]


def _check(
    path: Path,
    file: str,
    extra: Sequence[str],
    kind: str | None,
    result: CheckResult,
) -> None:
    if not file:
        result.problems.append(Finding("<unknown>", None, "an empty file name"))
        return
    if path.is_dir():
        empty = expand_files([file]) == [file]
        what = "a directory with no YAML files" if empty else "a directory, not a file"
        result.problems.append(Finding(file, None, what))
        return
    try:
        text = yamlio.read_text(path)
    except yamlio.YamlError as e:
        result.problems += findings_of([e.problem], file)
        return
    result.kind = kind or detect_kind(text)
    search_path = default_search_path(path, extra)
    checker = {
        "definition": _check_definition,
        "process": _check_process,
        "design": _check_design,
        "model": _check_model,
    }[result.kind]
    checker(path, file, search_path, result)


def _check_definition(
    path: Path, file: str, search_path: Sequence[str], result: CheckResult
) -> None:
    from malcolm.config import ConfigError, expand, load_definition
    from malcolm.config.build import check_block
    from malcolm.config.registry import check_kinds

    try:
        definition = load_definition(path)
    except ConfigError as e:
        result.problems += findings_of(e, file)
        return
    try:
        check_kinds(definition.sections)
    except ConfigError as e:
        result.problems += findings_of(e, file)
    values = {
        p.name: _PLACEHOLDERS.get(p.type, "CHECK:BLOCK")
        for p in definition.params
        if p.default is None
    }
    try:
        expanded = expand(definition, values, search_path, mri="CHECK")
    except ConfigError as e:
        result.problems += findings_of(e, file)
        return
    if result.problems:
        return  # unknown kinds: checking the build would only repeat them
    try:
        check_block(expanded, search_path)
    except ConfigError as e:
        result.problems += findings_of(e, file)


def _check_process(
    path: Path, file: str, search_path: Sequence[str], result: CheckResult
) -> None:
    from malcolm.config import ConfigError
    from malcolm.config.build import check_process

    try:
        check_process(path, search_path=tuple(search_path))
    except ConfigError as e:
        result.problems += findings_of(e, file)


def _check_design(
    path: Path, file: str, search_path: Sequence[str], result: CheckResult
) -> None:
    from malcolm.config import ConfigError
    from malcolm.parts.design import load_design

    try:
        load_design(path)
    except ConfigError as e:
        result.problems += findings_of(e, file)


def _check_model(
    path: Path, file: str, search_path: Sequence[str], result: CheckResult
) -> None:
    from malcolm.fsm import ModelError, check_model, load_model, resolve_controller

    try:
        model = load_model(path)
    except ModelError as e:
        result.problems += findings_of(e, file)
        return
    try:
        provider = resolve_controller(model)
    except ModelError as e:
        result.problems += findings_of(e, file)
        provider = None
    result.problems += findings_of(list(check_model(model, provider)), file)

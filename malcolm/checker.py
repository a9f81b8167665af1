"""``malcolm check``: find every problem in definitions, process files,
saved designs and state-machine models, without starting anything.

The kind of a file is decided by its content (see :func:`detect_kind`):

- a **model** has top-level ``states:`` or ``transitions:`` (or ``extends``,
  ``initial``, ``phases``);
- a **process** file has ``include``, ``define.*`` sections, or ``block.*``
  sections that give an ``mri``;
- a **design** (saved settings) has ``parts.ModelPart``, ``PalettePart``,
  ``ExportPart``, ``FollowerPart`` or ``fixed.*`` sections;
- anything else is a block **definition**.

Each kind is loaded with its own loader and then checked more deeply (see
:func:`check_file`). Every problem is a :class:`Finding` that prints as
``file:line: message`` (or ``file: message`` when no line applies).
Checking never raises: anything unexpected becomes an ``internal error``
finding.
"""

from __future__ import annotations

import re
import sys
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

__all__ = [
    "KINDS",
    "CheckResult",
    "Finding",
    "check_file",
    "check_files",
    "default_search_path",
    "detect_kind",
    "run_check",
]

KINDS = ("definition", "process", "design", "model")

DESIGN_KINDS = frozenset(
    {"parts.ModelPart", "parts.PalettePart", "parts.ExportPart", "parts.FollowerPart"}
)

#: Top-level keys of a state-machine model (a definition's have a dot).
MODEL_KEYS = frozenset({"states", "transitions", "extends", "initial", "phases"})

_TOP_KEY = re.compile(r"""^(?:"([^"\n]*)"|'([^'\n]*)'|([^\s#'"\-?:][^:\n#]*?))\s*:""")
_INDENTED_KEY = re.compile(r"""^[ \t]+(?:-[ \t]+)?["']?([\w.-]+)["']?\s*:""")

#: Placeholder values of each type, to expand a definition whose required
#: parameters have no defaults.
_PLACEHOLDERS = {"String": "CHECK", "Int": 1, "Float": 1.0, "Boolean": False}


@dataclass(frozen=True)
class Finding:
    """One problem: ``file:line: message`` (``file: message`` with no line)."""

    file: str
    line: int | None
    message: str

    def __str__(self) -> str:
        message = self.message.replace("\r", "\\r").replace("\n", "\\n")
        message = message.strip() or "(no message)"
        file = self.file or "<unknown>"
        if self.line is None:
            return f"{file}: {message}"
        return f"{file}:{self.line}: {message}"


@dataclass
class CheckResult:
    """What checking one file found."""

    file: str
    kind: str | None  #: one of KINDS, or None if the file could not be read
    problems: list[Finding] = field(default_factory=list)
    #: deeper checks that were skipped, and why (e.g. a loader not written yet)
    skipped: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.problems


def _findings(error: Any, default_file: str) -> list[Finding]:
    """The problems of a ConfigError or ModelError as findings."""
    out = []
    for p in getattr(error, "problems", None) or []:
        out.append(
            Finding(
                str(getattr(p, "file", "") or default_file),
                getattr(p, "line", None),
                str(getattr(p, "message", p)),
            )
        )
    return out or [Finding(default_file, None, str(error))]


def _top_level_keys(text: str) -> list[tuple[str, int]]:
    """``(key, line index)`` of every top-level mapping key, by text alone."""
    keys = []
    for i, line in enumerate(text.splitlines()):
        m = _TOP_KEY.match(line)
        if m:
            keys.append((next(g for g in m.groups() if g is not None).strip(), i))
    return keys


def detect_kind(text: str) -> str:
    """``"model"``, ``"process"``, ``"design"`` or ``"definition"``, by content.

    Only the text is looked at (top-level keys, and the keys under each
    ``block.*``), so that a file too broken to parse still gets the loader
    that will explain what is wrong with it.
    """
    text = text.lstrip("\ufeff")  # a BOM is not part of the first key
    keys = _top_level_keys(text)
    names = [k for k, _ in keys]
    if any(k in MODEL_KEYS for k in names):
        return "model"
    if "include" in names or any(k.startswith("define.") for k in names):
        return "process"
    lines = text.splitlines()
    for n, (key, start) in enumerate(keys):
        if key.startswith("block."):
            end = keys[n + 1][1] if n + 1 < len(keys) else len(lines)
            for line in lines[start + 1 : end]:
                m = _INDENTED_KEY.match(line)
                if m and m.group(1) == "mri":
                    return "process"
            if re.search(r"[{,]\s*mri\s*:", lines[start]):
                return "process"
    if any(k in DESIGN_KINDS or k.startswith("fixed.") for k in names):
        return "design"
    return "definition"


def default_search_path(path: Path, extra: Sequence[str] = ()) -> list[str]:
    """Where definitions named in ``path`` are looked for (after
    ``malcolm/blocks``): the ``extra`` directories, then a ``blocks/``
    directory next to the file or next to its directory, then the
    directory a definition's own ``Module.Name`` implies (two levels up).
    """
    dirs = [str(d) for d in extra]
    here = path.resolve().parent
    cwd = Path.cwd()
    for d in (here / "blocks", here.parent / "blocks", here.parent, here):
        if d.is_dir():
            name = str(d.relative_to(cwd)) if d.is_relative_to(cwd) else str(d)
            if name not in dirs:
                dirs.append(name)
    return dirs


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
        data = path.read_bytes()
    except OSError as e:
        result.problems.append(
            Finding(file, None, f"cannot read file: {e.strerror or e}")
        )
        return
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        line = data.count(b"\n", 0, e.start) + 1
        result.problems.append(Finding(file, line, f"file is not UTF-8: {e.reason}"))
        return
    result.kind = kind or detect_kind(text)
    _register_builtins(result)
    search_path = default_search_path(path, extra)
    checker = {
        "definition": _check_definition,
        "process": _check_process,
        "design": _check_design,
        "model": _check_model,
    }[result.kind]
    checker(path, file, search_path, result)


def _register_builtins(result: CheckResult) -> None:
    """Make malcolm's own section kinds known to the registry, if they exist."""
    try:
        import malcolm.config.builtin  # noqa: F401
    except Exception as e:  # not written yet, or broken: check without them
        result.skipped.append(f"built-in section kinds ({type(e).__name__}: {e})")


def _check_definition(
    path: Path, file: str, search_path: Sequence[str], result: CheckResult
) -> None:
    from malcolm.config import ConfigError, expand, load_definition
    from malcolm.config.registry import check_kinds

    try:
        definition = load_definition(path)
    except ConfigError as e:
        result.problems += _findings(e, file)
        return
    try:
        check_kinds(definition.sections)
    except ConfigError as e:
        result.problems += _findings(e, file)
    values = {
        p.name: _PLACEHOLDERS.get(p.type, "CHECK:BLOCK")
        for p in definition.params
        if p.default is None
    }
    try:
        expanded = expand(definition, values, search_path, mri="CHECK")
    except ConfigError as e:
        result.problems += _findings(e, file)
        return
    try:
        from malcolm.config.build import build_block
    except Exception as e:  # not written yet, or broken: check kinds only
        result.skipped.append(f"building the block ({type(e).__name__}: {e})")
        for block in expanded.walk():
            if block is expanded:
                continue
            try:
                sections = list(block.sections)
                if block.controller is not None:
                    sections.append(block.controller)
                check_kinds(sections)
            except ConfigError as e:
                result.problems += _findings(e, file)
        return
    if result.problems:
        return  # unknown kinds: building would only repeat them
    from malcolm.core import Process

    try:
        build_block(Process("check"), expanded, search_path)
    except ConfigError as e:
        result.problems += _findings(e, file)


def _check_process(
    path: Path, file: str, search_path: Sequence[str], result: CheckResult
) -> None:
    from malcolm.config import ConfigError, expand_process, load_process_file
    from malcolm.config.registry import check_kinds

    try:
        spec = load_process_file(path, search_path)
        blocks = expand_process(spec, search_path)
    except ConfigError as e:
        result.problems += _findings(e, file)
        return
    try:
        from malcolm.config.build import build_process
    except Exception as e:  # not written yet, or broken: check without it
        result.skipped.append(f"building the blocks ({type(e).__name__}: {e})")
        for top in blocks:
            for block in top.walk():
                sections = list(block.sections)
                if block.controller is not None:
                    sections.append(block.controller)
                try:
                    check_kinds(sections)
                except ConfigError as e:
                    result.problems += _findings(e, file)
        return
    try:
        build_process(path, search_path=tuple(search_path))
    except ConfigError as e:
        result.problems += _findings(e, file)


def _check_design(
    path: Path, file: str, search_path: Sequence[str], result: CheckResult
) -> None:
    from malcolm.config import ConfigError

    try:
        from malcolm.parts.design import load_design
    except Exception as e:  # not written yet, or broken: check the YAML only
        from malcolm.config import load_sections

        result.skipped.append(f"design checks ({type(e).__name__}: {e})")
        try:
            load_sections(path)
        except ConfigError as e:
            result.problems += _findings(e, file)
        return
    try:
        load_design(path)
    except ConfigError as e:
        result.problems += _findings(e, file)


def _check_model(
    path: Path, file: str, search_path: Sequence[str], result: CheckResult
) -> None:
    from malcolm.fsm import ModelError, check_model, load_model, resolve_controller

    try:
        model = load_model(path)
    except ModelError as e:
        result.problems += _findings(e, file)
        return
    try:
        provider = resolve_controller(model)
    except ModelError as e:
        result.problems += _findings(e, file)
        provider = None
    result.problems += _findings_of(check_model(model, provider), file)


def _findings_of(problems: Iterable[Any], file: str) -> list[Finding]:
    return [Finding(str(p.file or file), p.line, str(p.message)) for p in problems]


def expand_files(paths: Iterable[str]) -> list[str]:
    """``paths`` with each directory replaced by the YAML files under it
    (sorted; a directory with none stays, to be reported)."""
    files: list[str] = []
    for p in paths:
        if not p:  # Path("") would be the working directory
            files.append(p)
            continue
        path = Path(p)
        found = []
        try:
            if path.is_dir():
                found = sorted(
                    str(f)
                    for pattern in ("*.yaml", "*.yml")
                    for f in path.rglob(pattern)
                    if f.is_file()
                )
        except OSError:
            found = []
        files += found or [str(p)]
    return files


def _emit(line: str, stream: TextIO) -> None:
    """Write a line even if the stream cannot encode every character."""
    try:
        stream.write(line + "\n")
    except UnicodeEncodeError:
        encoding = getattr(stream, "encoding", None) or "ascii"
        stream.write(line.encode(encoding, "backslashreplace").decode(encoding) + "\n")


def run_check(
    files: Sequence[str],
    search_path: Sequence[str] = (),
    kind: str | None = None,
    verbose: bool = False,
    out: TextIO | None = None,
    err: TextIO | None = None,
) -> int:
    """Check ``files``: problems to ``out``, a summary to ``err``; 1 if any."""
    out = out or sys.stdout
    err = err or sys.stderr
    bad = total = 0
    files = expand_files(files)
    for f in files:
        result = check_file(f, search_path, kind)
        for problem in result.problems:
            _emit(str(problem), out)
        total += len(result.problems)
        bad += not result.ok
        if verbose:
            status = "ok" if result.ok else f"{_count(len(result.problems))}"
            _emit(f"{f}: {status} ({result.kind or 'unreadable'})", err)
            for why in result.skipped:
                _emit(f"{f}: skipped {why}", err)
    out.flush()
    n = len(files)
    if total:
        _emit(f"malcolm check: {_count(total)} in {bad} of {_files(n)}", err)
        return 1
    _emit(f"malcolm check: {_files(n)} OK", err)
    return 0


def _count(n: int) -> str:
    return f"{n} problem" + ("" if n == 1 else "s")


def _files(n: int) -> str:
    return f"{n} file" + ("" if n == 1 else "s")

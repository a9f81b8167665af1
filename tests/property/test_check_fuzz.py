"""Mangled definitions, process files, designs and models never make
`malcolm check` (or the loaders under it) fail with anything but a report.

Each example takes a real file (the design document's fixtures, the packaged
``malcolm/blocks`` definitions, the models), mutates a few lines, writes it
next to the original in a copy of the tree (so includes and child
definitions still resolve), and checks that:

- ``malcolm check FILE`` exits 0 or 1, prints only ``file:line: message`` or
  ``file: message`` lines on stdout, never a traceback and never an
  ``internal error``;
- the loader for the file's kind returns a result or raises its own error
  (ConfigError, or ModelError for a model), never another exception.
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from malcolm.checker import detect_kind
from malcolm.cli import main
from malcolm.config import (
    ConfigError,
    expand,
    expand_process,
    load_definition,
    load_process_file,
)
from malcolm.fsm import ModelError, load_model
from malcolm.parts.design import load_design

ROOT = Path(__file__).resolve().parents[2]
FIXTURES = ROOT / "tests/unit/config_fixtures"
PACKAGED = ROOT / "malcolm/blocks"
MODEL_DIRS = [ROOT / "models", ROOT / "tests/property/fixtures"]

SOURCES = {
    "fixtures": (FIXTURES, sorted(FIXTURES.rglob("*.yaml"))),
    "packaged": (PACKAGED, sorted(PACKAGED.rglob("*.yaml"))),
    "models": (ROOT, [p for d in MODEL_DIRS for p in sorted(d.glob("*.yaml"))]),
}
CORPUS = [(name, path) for name, (_, paths) in SOURCES.items() for path in paths]

PROBLEM_LINE = re.compile(r"^.+:\d+: .+$|^.+: .+$")

SETTINGS = settings(
    max_examples=250,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)

TEXT = st.text(alphabet=st.characters(exclude_categories=("Cs",)), max_size=16)
YAMLISH = st.text(alphabet=" \t-:{}[],#&*!|>'\"?%@`.abc1{x}\\", max_size=16)
NUMBER = st.one_of(
    st.integers(-(10**20), 10**20).map(str),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
)
VALUE = st.one_of(TEXT, YAMLISH, NUMBER, st.sampled_from(["", "~", "[]", "{}"]))


@st.composite
def mutated(draw):
    """(source name, file, mutated text): a few lines deleted, duplicated,
    swapped, re-indented, given new values, braced, or the text cut short."""
    name, path = draw(st.sampled_from(CORPUS))
    lines = path.read_text().split("\n")
    for _ in range(draw(st.integers(1, 4))):
        i = draw(st.integers(0, len(lines) - 1))
        line = lines[i]
        op = draw(
            st.sampled_from(
                [
                    "delete",
                    "duplicate",
                    "swap",
                    "indent",
                    "dedent",
                    "value",
                    "unknown",
                    "insert",
                    "truncate",
                ]
            )
        )
        if op == "delete" and len(lines) > 1:
            del lines[i]
        elif op == "duplicate":
            lines.insert(i, line)
        elif op == "swap":
            j = draw(st.integers(0, len(lines) - 1))
            lines[i], lines[j] = lines[j], line
        elif op == "indent":
            lines[i] = draw(st.sampled_from([" ", "  ", "    ", "\t"])) + line
        elif op == "dedent":
            lines[i] = line[draw(st.integers(1, 6)) :]
        elif op == "value":
            key, sep, _ = line.partition(":")
            lines[i] = key + (sep or ":") + " " + draw(VALUE)
        elif op == "unknown":
            at = draw(st.integers(0, len(line)))
            lines[i] = line[:at] + "{unknown}" + line[at:]
        elif op == "insert":
            lines.insert(i, draw(VALUE))
        else:  # truncate the whole text at a random character
            text = "\n".join(lines)
            text = text[: draw(st.integers(0, len(text)))]
            lines = text.split("\n")
    return name, path, "\n".join(lines)


@pytest.fixture(scope="module")
def tree(tmp_path_factory):
    """A copy of every corpus directory: mutants are written inside it."""
    root = tmp_path_factory.mktemp("check_fuzz")
    for name, (base, paths) in SOURCES.items():
        for path in paths:
            target = root / name / path.relative_to(base)
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy(path, target)
    return root


def write_mutant(tree: Path, case) -> Path:
    name, path, text = case
    base = SOURCES[name][0]
    target = tree / name / path.relative_to(base).with_name(f"Mutant{path.stem}.yaml")
    target.write_text(text, encoding="utf-8")
    return target


def search_path(tree: Path) -> list[Path]:
    return [tree / "fixtures" / "blocks"]


@SETTINGS
@given(case=mutated())
def test_check_reports_problems_and_never_crashes(tree, capsys, case):
    target = write_mutant(tree, case)
    status = main(["check", "-I", str(search_path(tree)[0]), str(target)])
    out, err = capsys.readouterr()
    assert status in (0, 1)
    assert "Traceback" not in out + err
    assert "internal error" not in out, out
    for line in out.splitlines():
        assert PROBLEM_LINE.match(line), line
    assert (status == 1) == bool(out.strip())


def placeholder(param):
    return {"Int": 1, "Float": 1.5, "Boolean": True}.get(param.type, "BL:X")


@SETTINGS
@given(case=mutated())
def test_loaders_return_or_raise_their_own_error(tree, case):
    target = write_mutant(tree, case)
    kind = detect_kind(case[2])
    sp = search_path(tree)
    try:
        if kind == "model":
            load_model(target)
        elif kind == "process":
            expand_process(load_process_file(target, sp), sp)
        elif kind == "design":
            load_design(target)
        else:
            definition = load_definition(target)
            values = {p.name: placeholder(p) for p in definition.params}
            expand(definition, values, sp, mri="BL:TOP")
    except (ConfigError, ModelError) as error:
        assert error.problems
        for problem in error.problems:
            assert problem.file and problem.message
            assert problem.line is None or problem.line >= 1

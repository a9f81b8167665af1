"""Mangled definitions load or raise ConfigError, never anything else."""

import shutil
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from malcolm.config.definitions import expand, load_definition
from malcolm.config.errors import ConfigError
from malcolm.config.process_file import expand_process, load_process_file
from malcolm.config.yamlsections import parse_sections

FIXTURES = Path(__file__).parent / "config_fixtures"
DEFINITIONS = sorted((FIXTURES / "blocks").rglob("*.yaml")) + [
    FIXTURES / "designs/PositionBased.yaml"
]
PROCESS_FILES = sorted((FIXTURES / "process").glob("*.yaml"))

SETTINGS = settings(
    max_examples=150,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)

TEXT = st.text(
    alphabet=st.characters(exclude_categories=("Cs",)),
    max_size=20,
)
YAMLISH = st.text(alphabet=" \t\n-:{}[],#&*!|>'\"?%@`.abc1{x}", max_size=20)


@st.composite
def mutated(draw, texts):
    """A fixture text with a few lines deleted, repeated, moved or garbled."""
    path = draw(st.sampled_from(texts))
    lines = path.read_text().split("\n")
    for _ in range(draw(st.integers(1, 4))):
        i = draw(st.integers(0, len(lines) - 1))
        op = draw(
            st.sampled_from(
                ["delete", "duplicate", "indent", "dedent", "value", "unknown", "text"]
            )
        )
        line = lines[i]
        if op == "delete" and len(lines) > 1:
            del lines[i]
        elif op == "duplicate":
            lines.insert(i, line)
        elif op == "indent":
            lines[i] = " " * draw(st.integers(1, 6)) + line
        elif op == "dedent":
            lines[i] = line[draw(st.integers(1, 6)) :]
        elif op == "value":
            key, sep, _ = line.partition(":")
            lines[i] = key + (sep or ":") + " " + draw(st.one_of(TEXT, YAMLISH))
        elif op == "unknown":
            at = draw(st.integers(0, len(line)))
            lines[i] = line[:at] + "{unknown}" + line[at:]
        else:
            lines.insert(i, draw(st.one_of(TEXT, YAMLISH)))
    return path, "\n".join(lines)


def value_for(param):
    return {"Int": 1, "Float": 1.5, "Boolean": True}.get(param.type, "BL:X")


@pytest.fixture(scope="module")
def tree(tmp_path_factory):
    root = tmp_path_factory.mktemp("config_fuzz")
    shutil.copytree(FIXTURES, root, dirs_exist_ok=True)
    return root


@SETTINGS
@given(mutated(DEFINITIONS))
def test_mutated_definitions(tree, case):
    source, text = case
    target = tree / source.relative_to(FIXTURES)
    target.write_text(text)
    try:
        definition = load_definition(target)
        values = {p.name: value_for(p) for p in definition.params}
        expand(definition, values, [tree / "blocks"], mri="BL:TOP")
    except ConfigError as error:
        assert error.problems
        for problem in error.problems:
            assert problem.line >= 1 and problem.file
            assert "\n" not in str(problem)
    finally:
        shutil.copy(source, target)


@SETTINGS
@given(mutated(PROCESS_FILES))
def test_mutated_process_files(tree, case):
    source, text = case
    target = tree / source.relative_to(FIXTURES)
    target.write_text(text)
    search = [tree / "blocks"]
    try:
        expand_process(load_process_file(target, search), search)
    except ConfigError as error:
        assert all(p.line >= 1 for p in error.problems)
    finally:
        shutil.copy(source, target)


@settings(max_examples=300, deadline=None)
@given(st.one_of(TEXT, YAMLISH, st.text(max_size=200).filter(str.isprintable)))
def test_random_text(text):
    try:
        parse_sections(text, "random.yaml")
    except ConfigError as error:
        assert all(p.file == "random.yaml" and p.line >= 1 for p in error.problems)

"""One line-aware YAML reader (malcolm.yamlio) for models, definitions and
generator files: the same document problem gets the same file:line message
from each of them."""

from __future__ import annotations

from pathlib import Path

import pytest

from malcolm import yamlio
from malcolm.config import ConfigError, load_sections
from malcolm.fsm import ModelError, load_model
from malcolm.scan.files import GeneratorFileError, read_generator_file


def problems_of_each_loader(path: Path) -> dict[str, list[str]]:
    """``file:line: message`` lines from each loader that reads ``path``."""
    found: dict[str, list[str]] = {}
    with pytest.raises(ModelError) as model:
        load_model(path)
    found["model"] = [str(p) for p in model.value.problems]
    with pytest.raises(ConfigError) as config:
        load_sections(path)
    found["definition"] = [str(p) for p in config.value.problems]
    with pytest.raises(GeneratorFileError) as points:
        read_generator_file(path)
    found["points"] = [str(points.value)]
    return found


@pytest.mark.parametrize(
    ("text", "line", "message"),
    [
        ("a.b:\n  x: &a 1\n  y: *a\n", 3, "YAML error: aliases (*name) are not"),
        ("a.b:\n  x: 1\n y: 2\n", 3, "YAML error: "),
        ("a.b:\n  x: {k: 1, k: 2}\n", 2, "duplicate key 'k' (first given at line 2)"),
        ("a.b:\n  x: 1\n# \x1f\n", 3, "YAML error: special characters"),
        ("a.b:\n  x: !!python/name:os.system\n", 2, "bad value: "),
        ("a.b:\n  x: !custom [1]\n", 2, "unsupported YAML tag !custom"),
    ],
)
def test_every_loader_reports_a_yaml_problem_alike(tmp_path, text, line, message):
    path = tmp_path / "doc.yaml"
    path.write_text(text)
    for loader, lines in problems_of_each_loader(path).items():
        assert lines[0].startswith(f"{path}:{line}: {message}"), (loader, lines)


def test_a_byte_that_is_not_utf8_is_reported_at_its_line(tmp_path):
    path = tmp_path / "doc.yaml"
    path.write_bytes(b"a.b:\n  x: 1\n  y: \xff\n")
    for loader, lines in problems_of_each_loader(path).items():
        assert lines == [f"{path}:3: file is not UTF-8: invalid start byte"], loader


def test_lines_of_keys_values_and_items():
    data, problems = yamlio.load("d.yaml", "top:\n  key:\n    - 1\n    - [2]\n")
    assert problems == []
    assert data.line_of("top") == 1
    inner = data["top"]
    assert (inner.key_lines["key"], inner.value_lines["key"]) == (2, 3)
    assert inner["key"].item_lines == [3, 4]
    assert dict(yamlio.value_lines(data)) == {
        ("top",): 2,
        ("top", "key"): 3,
        ("top", "key", 0): 3,
        ("top", "key", 1): 4,
        ("top", "key", 1, 0): 4,
    }
    assert type(yamlio.plain(data)["top"]["key"]) is list


def test_a_fallback_rewrites_text_that_does_not_parse():
    node, text = yamlio.compose("a: {b}:c\n", "f.yaml", lambda t: "a: '{b}:c'\n")
    assert text == "a: '{b}:c'\n"
    assert yamlio.construct(node)[0] == {"a": "{b}:c"}
    with pytest.raises(yamlio.YamlError) as info:
        yamlio.compose("a: [\n", "f.yaml")
    assert str(info.value).startswith("f.yaml:2: YAML error: ")


def test_a_file_that_cannot_be_read(tmp_path):
    with pytest.raises(yamlio.YamlError) as info:
        yamlio.read_text(tmp_path / "absent.yaml")
    assert info.value.problem.line is None
    assert "cannot read file: No such file" in str(info.value)

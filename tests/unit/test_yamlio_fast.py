"""yamlio reads with libyaml where PyYAML has it (issue 8: a process file of
a thousand blocks, every model), and gives what the pure-Python composer
gives: the same nodes and lines for every file malcolm ships, and that
composer's words for every problem."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from yaml.nodes import MappingNode, Node, ScalarNode, SequenceNode

from malcolm import yamlio
from malcolm.config.yamlsections import quote_references

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = sorted(
    [*(ROOT / "models").glob("*.yaml"), *(ROOT / "malcolm" / "blocks").rglob("*.yaml")]
)

needs_libyaml = pytest.mark.skipif(
    yamlio._CLoader is None, reason="PyYAML was built without libyaml"
)


def shape(node: Node | None) -> object:
    """What a reader of the tree sees: tags, values, flow style and lines."""
    if node is None:
        return None
    line = node.start_mark.line
    if isinstance(node, ScalarNode):
        return ("scalar", node.tag, node.value, line, node.style or None)
    if isinstance(node, SequenceNode):
        return ("seq", node.tag, line, node.flow_style, [shape(n) for n in node.value])
    assert isinstance(node, MappingNode)
    pairs = [(shape(k), shape(v)) for k, v in node.value]
    return ("map", node.tag, line, node.flow_style, pairs)


@needs_libyaml
@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.name)
def test_libyaml_reads_every_shipped_file_as_the_python_composer_does(
    path: Path,
) -> None:
    text = path.read_text()
    node, used = yamlio.compose(text, str(path), fallback=quote_references)
    try:
        expected = yamlio._compose_once(text)
        expected_text = text
    except yaml.YAMLError:
        expected_text = quote_references(text)
        expected = yamlio._compose_once(expected_text)
    assert used == expected_text
    assert shape(node) == shape(expected)


@needs_libyaml
def test_the_fast_reader_is_the_one_used(monkeypatch: pytest.MonkeyPatch) -> None:
    def refuse(text: str) -> None:
        raise AssertionError("the pure-Python composer was used")

    monkeypatch.setattr(yamlio, "_compose_once", refuse)
    node, _ = yamlio.compose("a: [1, 2]\nb: {c: d}\n")
    assert shape(node) == (
        "map",
        yamlio.MAP_TAG,
        0,
        False,
        [
            (
                ("scalar", yamlio.STR_TAG, "a", 0, None),
                (
                    "seq",
                    yamlio.SEQ_TAG,
                    0,
                    True,
                    [
                        ("scalar", "tag:yaml.org,2002:int", "1", 0, None),
                        ("scalar", "tag:yaml.org,2002:int", "2", 0, None),
                    ],
                ),
            ),
            (
                ("scalar", yamlio.STR_TAG, "b", 1, None),
                (
                    "map",
                    yamlio.MAP_TAG,
                    1,
                    True,
                    [
                        (
                            ("scalar", yamlio.STR_TAG, "c", 1, None),
                            ("scalar", yamlio.STR_TAG, "d", 1, None),
                        )
                    ],
                ),
            ),
        ],
    )


@pytest.mark.parametrize(
    ("text", "line", "message"),
    [
        ("a:\n  x: &a [1]\n  y: *a\n", 3, "YAML error: aliases (*name) are not"),
        ("a:\n  x: &a 1\n  y:\n    - *a\n", 4, "YAML error: aliases (*name) are not"),
        ("a:\n  x: 1\n y: 2\n", 3, "YAML error: "),
        ("a: 1\n---\nb: 2\n", 2, "YAML error: expected a single document"),
    ],
)
def test_problems_are_the_python_composers(text: str, line: int, message: str) -> None:
    with pytest.raises(yamlio.YamlError) as info:
        yamlio.compose(text, "doc.yaml")
    assert str(info.value).startswith(f"doc.yaml:{line}: {message}")


def test_an_anchor_without_an_alias_is_read() -> None:
    node, _ = yamlio.compose("a: &x 1\nb: 2\n")
    data, problems = yamlio.construct(node)
    assert (data, problems) == ({"a": 1, "b": 2}, [])


def test_a_deeply_nested_document_is_a_problem_not_a_crash() -> None:
    text = "a: " + "[" * 5000 + "]" * 5000 + "\n"
    with pytest.raises(yamlio.YamlError, match="nested too deeply|YAML error"):
        node, _ = yamlio.compose(text, "deep.yaml")
        yamlio.construct(node, "deep.yaml")

"""The snippets of README.md and docs/{cli,config,definitions,scan}.md run
as written, and the output they show is the output malcolm gives, so the
docs cannot drift from the code again (issue 7, docs).

- every ```python block runs (from the top of the checkout); a line
  ``expression  # literal`` also checks the expression's value;
- a plain block that starts ``$ malcolm ...`` is run, and its other lines
  are the stdout expected (``...`` in a line stands for any text); the
  ```yaml blocks that start ``# path`` are written out first;
- every ``malcolm`` command of a ```sh block of docs/cli.md is run or named
  below as one that cannot run here;
- ```yaml and ```toml blocks parse.
"""

from __future__ import annotations

import ast
import re
import shlex
import tomllib
from dataclasses import dataclass
from pathlib import Path

import pytest

from malcolm.cli import main
from malcolm.config import parse_sections
from malcolm.core import Process
from malcolm.parts.soft import CAEnumPart

from .scans import compound, run

ROOT = Path(__file__).resolve().parents[2]
FIXTURES = ROOT / "tests" / "unit" / "config_fixtures"
DOCS = [ROOT / "README.md"] + [
    ROOT / "docs" / f"{name}.md" for name in ("cli", "config", "definitions", "scan")
]
#: where each doc's `$ malcolm` samples run (None: a fresh directory)
SAMPLE_DIRS = {"cli.md": FIXTURES, "config.md": FIXTURES, "definitions.md": None}
#: `malcolm` commands of docs/cli.md's sh blocks that are run (from the top
#: of the checkout, without redirections and pipes) ...
RUN = {
    "malcolm demo --scan",
    "malcolm check malcolm/blocks models",
    "malcolm graph runnable_device",
    "malcolm graph stateful --format dot",
}
#: ... and those that cannot be: they serve until stopped, or name your files
NOT_RUN = {
    "malcolm serve malcolm/blocks/demo/process.yaml",
    "malcolm serve beamline.yaml -I /dls/blocks",
    "malcolm check -I my/blocks beamline.yaml designs/*.yaml",
}


@dataclass(frozen=True)
class Block:
    doc: str
    line: int
    lang: str
    text: str

    def __str__(self) -> str:
        return f"{self.doc}:{self.line}"


def blocks(path: Path) -> list[Block]:
    """Every fenced block of ``path``, dedented."""
    found = []
    lines = path.read_text().splitlines()
    i = 0
    while i < len(lines):
        match = re.fullmatch(r"( *)```(\w*)", lines[i])
        if match is None:
            i += 1
            continue
        indent, start = len(match[1]), i
        body = []
        i += 1
        while lines[i].strip() != "```":
            body.append(lines[i][indent:])
            i += 1
        found.append(Block(path.name, start + 1, match[2], "\n".join(body) + "\n"))
        i += 1
    return found


def all_blocks(lang: str) -> list[Block]:
    return [b for doc in DOCS for b in blocks(doc) if b.lang == lang]


def samples() -> list[Block]:
    return [b for b in all_blocks("") if b.text.startswith("$ malcolm ")]


# ---- README


def test_the_readme_opens_with_the_two_commands_of_a_fresh_machine():
    first = (
        "python3 -m venv .venv && .venv/bin/pip install -e . && "
        ".venv/bin/malcolm demo\n"
    )
    second = (
        'python3 -m venv .venv && .venv/bin/pip install -e ".[test]" && '
        ".venv/bin/pytest tests\n"
    )
    text = (ROOT / "README.md").read_text()
    assert text.startswith(f"# malcolm\n\n```sh\n{first}{second}```\n")


def test_the_readme_part_opens_the_shutter_when_a_scan_is_configured():
    (example,) = [b for b in all_blocks("python") if b.doc == "README.md"]
    namespace: dict = {}
    exec(compile(example.text, str(example), "exec"), namespace)
    shutter_part = namespace["ShutterPart"]
    from malcolm.controllers.runnable import RunnableController
    from malcolm.controllers.stateful import StatefulController

    async def scenario():
        process = Process("readme")
        choices = ["Closed", "Open"]
        shutter = CAEnumPart("shutter", "BL:SHUTTER", choices=choices, writeable=True)
        process.add_controller(StatefulController("BL:SHUTTER", [shutter]))
        part = shutter_part("shutter", "BL:SHUTTER")
        process.add_controller(RunnableController("BL:SCAN", [part]))
        await process.start()
        try:
            before = process.get_block("BL:SHUTTER").shutter.value
            generator = compound(("x", 2))
            await process.post(["BL:SCAN", "configure"], {"generator": generator})
            return before, process.get_block("BL:SHUTTER").shutter.value
        finally:
            await process.stop()

    assert run(scenario) == ("Closed", "Open")


# ---- python snippets


def literal_of(line: str) -> tuple[bool, object]:
    """``(True, value)`` if ``line`` ends ``  # <a Python literal>``."""
    _, mark, comment = line.partition("  # ")
    try:
        return bool(mark), ast.literal_eval(comment.strip())
    except (ValueError, SyntaxError):
        return False, None


def run_snippet(block: Block) -> None:
    """Run ``block`` statement by statement; an expression statement whose
    line ends in a literal comment must have that value."""
    lines = block.text.splitlines()
    namespace: dict = {}
    for statement in ast.parse(block.text).body:
        module = ast.Module([statement], type_ignores=[])
        if isinstance(statement, ast.Expr):
            found, value = literal_of(lines[statement.end_lineno - 1])
            result = eval(
                compile(ast.Expression(statement.value), str(block), "eval"), namespace
            )
            assert not found or result == value, (str(block), statement.lineno)
        else:
            exec(compile(module, str(block), "exec"), namespace)


@pytest.mark.parametrize(
    "block", [b for b in all_blocks("python") if b.doc != "README.md"], ids=str
)
def test_python_snippets_run_as_written(block, monkeypatch):
    monkeypatch.chdir(ROOT)
    run_snippet(block)


# ---- command samples


def written_files(doc: str) -> dict[str, str]:
    """The yaml blocks of ``doc`` that start with ``# path``."""
    files = {}
    for block in all_blocks("yaml"):
        first = block.text.splitlines()[0]
        if block.doc == doc and re.fullmatch(r"# [\w./-]+\.yaml", first):
            files[first[2:]] = block.text
    return files


def matches(expected: str, actual: str) -> bool:
    pattern = ".*".join(re.escape(part) for part in expected.split("..."))
    return re.fullmatch(pattern, actual) is not None


@pytest.mark.parametrize("block", samples(), ids=str)
def test_command_samples_show_what_malcolm_prints(block, tmp_path, monkeypatch, capsys):
    where = SAMPLE_DIRS[block.doc] or tmp_path
    for name, text in written_files(block.doc).items():
        (where / name).parent.mkdir(parents=True, exist_ok=True)
        (where / name).write_text(text)
    monkeypatch.chdir(where)
    command, *expected = block.text.splitlines()
    main(shlex.split(command)[2:])  # after "$ malcolm"
    actual = capsys.readouterr().out.splitlines()
    assert len(actual) == len(expected), (str(block), actual)
    for want, got in zip(expected, actual):
        assert matches(want, got), (str(block), want, got)


def cli_commands() -> list[str]:
    commands = []
    for block in blocks(ROOT / "docs" / "cli.md"):
        if block.lang == "sh":
            for line in block.text.splitlines():
                command = line.partition("#")[0].partition(">")[0].partition("|")[0]
                commands.append(" ".join(command.split()))
    return commands


def test_every_command_of_cli_md_is_run_or_named():
    assert set(cli_commands()) == RUN | NOT_RUN


@pytest.mark.parametrize("command", sorted(RUN))
def test_the_commands_of_cli_md_work(command, monkeypatch, capsys):
    monkeypatch.chdir(ROOT)
    assert main(command.split()[1:]) == 0
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err


# ---- yaml and toml


@pytest.mark.parametrize("block", all_blocks("yaml"), ids=str)
def test_yaml_snippets_parse(block):
    assert parse_sections(block.text, str(block), value_kinds={"include"})


@pytest.mark.parametrize("block", all_blocks("toml"), ids=str)
def test_toml_snippets_parse(block):
    assert tomllib.loads(block.text)

"""A scan is data from the caller, never the name of a file on the server
(issue 7 item 1); reading a generator file is `malcolm points`' own job."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from malcolm.cli import main
from malcolm.core import BadValueError
from malcolm.demo import demo_process
from malcolm.scan import GeneratorError, ScanPoints, scan_points
from malcolm.scan.files import GeneratorFileError, points_from_file

from .scans import compound, run

SECRET = "root:x:0:0:the first line of a secret file"


@pytest.fixture
def secret_generator(tmp_path: Path) -> Path:
    """A file that is both a valid generator and holds a secret first line."""
    path = tmp_path / "secret.yaml"
    path.write_text(
        f"# {SECRET}\n"
        "typeid: scanpointgenerator:generator/CompoundGenerator:1.0\n"
        "generators:\n"
        "  - typeid: scanpointgenerator:generator/LineGenerator:1.0\n"
        "    axes: [x]\n    units: [mm]\n    start: [0]\n    stop: [1]\n"
        "    size: 2\n    alternate: false\n"
        "excluders: []\nmutators: []\nduration: 0.001\n"
    )
    return path


@pytest.mark.parametrize("as_type", [str, Path])
def test_scan_points_refuses_a_file_name_without_reading_it(secret_generator, as_type):
    assert points_from_file(secret_generator).size == 2  # the file is valid
    with pytest.raises(GeneratorError) as info:
        scan_points(as_type(secret_generator))  # type: ignore[arg-type]
    message = str(info.value)
    assert "expected a mapping" in message and "never as the name of a file" in message
    assert SECRET not in message and "secret" not in message


def test_scan_points_takes_computed_points_as_they_are():
    points = scan_points(compound(("x", 2)))
    assert isinstance(points, ScanPoints)
    assert scan_points(points) is points


@pytest.mark.parametrize("generator", ["/etc/passwd", "relative/name.yaml", b"x"])
def test_configure_with_text_is_refused_and_changes_nothing(tmp_path, generator):
    secret = tmp_path / "secret.yaml"
    secret.write_text(SECRET + "\n")
    if generator == "relative/name.yaml":
        generator = os.path.relpath(secret)

    async def scenario():
        process = demo_process()
        await process.start()
        try:
            block = process.get_block("SCAN")
            with pytest.raises(BadValueError) as info:
                await process.post(["SCAN", "configure"], {"generator": generator})
            return str(info.value), block.state.value, block.totalSteps.value
        finally:
            await process.stop()

    message, state, total = run(scenario)
    assert "SCAN.configure" in message and "expected a mapping" in message
    assert "root:" not in message and SECRET not in message
    assert (state, total) == ("Ready", 0)


def test_a_bad_value_in_a_yaml_generator_file_is_reported_at_its_line(
    secret_generator, capsys
):
    text = secret_generator.read_text().replace("size: 2", "size: -3")
    secret_generator.write_text(text)
    with pytest.raises(GeneratorFileError) as info:
        points_from_file(secret_generator)
    assert (info.value.file, info.value.line) == (str(secret_generator), 9)
    assert main(["points", str(secret_generator)]) == 1
    assert capsys.readouterr().err == (
        f"{secret_generator}:9: generators[0].size: expected a positive integer,"
        " got -3\n"
    )


def test_a_yaml_syntax_error_in_a_generator_file_is_file_line_message(tmp_path, capsys):
    path = tmp_path / "g.yaml"
    path.write_text("typeid: x\ngenerators: [\n  {a: 1\n")
    assert main(["points", str(path)]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"{path}:4: YAML error: ")
    assert "\n" not in err.rstrip("\n")

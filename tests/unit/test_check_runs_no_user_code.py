"""A section may name only a registered type or a Part/Controller class, and
`malcolm check` runs no user code beyond importing it (issue 7 item 2);
what a constructor or add_part would refuse, check finds statically at its
line (issue 7 item 9)."""

from __future__ import annotations

import sys
import textwrap
import uuid
from pathlib import Path

import pytest

from malcolm.cli import main
from malcolm.config import ConfigError
from malcolm.config.build import build_definition

USER_MODULE = '''
from pathlib import Path

from malcolm.controllers.stateful import StatefulController
from malcolm.fsm import RunnableDevice, Stateful
from malcolm.parts import Part

MARKS = Path({marks!r})


def mark(what):
    MARKS.mkdir(exist_ok=True)
    (MARKS / what).touch()


class Marker(Part):
    """Leaves a mark when made, set up or hooked."""

    def __init__(self, name, gain: float = 1.0):
        mark("constructed")
        super().__init__(name)

    def setup(self, registrar):
        mark("setup")

    @Stateful.Reset
    def reset(self, task, device):
        mark("hooked")


class MarkingController(StatefulController):
    def __init__(self, mri, parts=(), description=""):
        mark("controller")
        super().__init__(mri, parts, description)


class TooMany(Part):
    @Stateful.Reset
    async def reset(self, task, device, extra):
        mark("hooked")


class Runner(Part):
    @RunnableDevice.Configure
    async def configure(self, task, device):
        mark("hooked")
'''


@pytest.fixture
def user(tmp_path, monkeypatch):
    """An importable user module whose classes leave marks in tmp/marks."""
    name = f"usermod_{uuid.uuid4().hex[:8]}"
    marks = tmp_path / "marks"
    (tmp_path / f"{name}.py").write_text(USER_MODULE.format(marks=str(marks)))
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.chdir(tmp_path)
    yield name, marks
    sys.modules.pop(name, None)


def check(capsys, *argv) -> tuple[int, list[str]]:
    status = main(["check", *map(str, argv)])
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err and "internal error" not in out
    return status, out.splitlines()


def write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(textwrap.dedent(text))
    return path


def test_a_function_named_as_a_section_is_refused_and_never_called(
    tmp_path, capsys, monkeypatch
):
    monkeypatch.chdir(tmp_path)
    d = write(tmp_path / "d.yaml", 'parts.os.system:\n    command: "touch PWNED"\n')
    status, out = check(capsys, d)
    assert status == 1
    assert out == [
        f"{d}:1: section type 'parts.os.system' names the function posix.system, "
        "not a Part class (a section names a registered section type or a Part "
        "subclass)"
    ]
    assert not (tmp_path / "PWNED").exists()


def test_serve_refuses_it_too(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    write(
        tmp_path / "blocks/evil/Box.yaml",
        'parts.os.system:\n    command: "touch PWNED"\n'
        "controller.subprocess.Popen:\n    args: touch PWNED2\n",
    )
    proc = write(tmp_path / "p.yaml", "block.evil.Box:\n    mri: BOX\n")
    assert main(["serve", str(proc)]) == 1
    err = capsys.readouterr().err
    assert "Box.yaml:1: section type 'parts.os.system' names the function" in err
    assert "Box.yaml:3: section type 'controller.subprocess.Popen' names the class" in (
        err
    )
    assert "not a Controller class" in err and "nothing started" in err
    assert not (tmp_path / "PWNED").exists() and not (tmp_path / "PWNED2").exists()


def test_check_imports_user_classes_but_never_makes_or_hooks_them(user, capsys):
    module, marks = user
    d = write(
        Path("d.yaml"),
        f"""\
        controller.{module}.MarkingController:
            description: mine
        parts.{module}.Marker:
            name: m
        ca.Double:
            name: x
            pv: X
        """,
    )
    assert check(capsys, d) == (0, [])
    assert not marks.exists()
    # building it (what serve does) makes them: the marks prove they would run
    build_definition(d, {}, "BOX")
    assert {p.name for p in marks.iterdir()} == {"controller", "constructed", "setup"}


def test_check_finds_a_user_class_keyword_problem_statically(user, capsys):
    module, marks = user
    d = write(
        Path("d.yaml"),
        f"parts.{module}.Marker:\n    name: m\n    gian: 2\n    gain: fast\n",
    )
    status, out = check(capsys, d)
    assert status == 1
    assert out == [
        f"d.yaml:3: parts.{module}.Marker: unknown parameter 'gian' (Marker takes "
        "name, gain) (did you mean 'gain'?)",
        f"d.yaml:4: parts.{module}.Marker: 'gain' must be a number, not 'fast'",
    ]
    assert not marks.exists()


def test_a_hook_with_the_wrong_signature_is_found_by_check(user, capsys):
    module, marks = user
    d = write(Path("d.yaml"), f"init.String:\n  name: p\nparts.{module}.TooMany:\n")
    status, out = check(capsys, d)
    assert status == 1
    assert out == [
        f"d.yaml:3: parts.{module}.TooMany: part 'TooMany', phase Reset: "
        "TooMany.reset(task, device, extra) needs 3 arguments; a hook function is "
        "called with (task, device)"
    ]
    with pytest.raises(ConfigError, match="needs 3 arguments"):
        build_definition(d, {"p": "x"}, "BOX")  # serve says the same
    assert not marks.exists()


def test_a_hook_into_a_phase_the_model_lacks_is_found_by_check(user, capsys):
    module, marks = user
    d = write(Path("d.yaml"), f"parts.{module}.Runner:\n    name: r\n")
    status, out = check(capsys, d)
    assert status == 1
    assert out[0].startswith(f"d.yaml:1: parts.{module}.Runner: CHECK: part 'r'")
    assert "phase 'Configure', which model Stateful does not have" in out[0]
    assert not marks.exists()


@pytest.mark.parametrize(
    ("value", "shown"), [(".nan", "nan"), ("-1", "-1"), ("0", "0"), (".inf", "inf")]
)
def test_a_bad_phase_timeout_is_found_by_check_at_its_line(
    tmp_path, capsys, value, shown
):
    d = write(
        tmp_path / "d.yaml",
        f"""\
        controller.RunnableController:
            description: m
            phase_timeout: {value}
        """,
    )
    status, out = check(capsys, d)
    assert status == 1
    assert out == [
        f"{d}:3: controller.RunnableController: phase_timeout must be a positive,"
        f" finite number of seconds, not {shown}"
    ]


def test_a_bad_timeout_of_one_phase_is_found_at_its_line(tmp_path, capsys):
    d = write(
        tmp_path / "d.yaml",
        """\
        controller.RunnableController:
            phase_timeouts:
                Configure: 5
                Run: -1
        """,
    )
    status, out = check(capsys, d)
    assert status == 1
    assert out == [
        f"{d}:4: controller.RunnableController: phase_timeouts.Run must be a"
        " positive, finite number of seconds, not -1"
    ]


def test_a_user_controller_with_a_bad_default_timeout(tmp_path, capsys, monkeypatch):
    name = f"userctl_{uuid.uuid4().hex[:8]}"
    (tmp_path / f"{name}.py").write_text(
        "from malcolm.controllers.stateful import StatefulController\n\n\n"
        "class Hasty(StatefulController):\n"
        "    def __init__(self, mri, parts=(), phase_timeout=0):\n"
        "        raise AssertionError('never made by check')\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    d = write(tmp_path / "d.yaml", f"controller.{name}.Hasty:\n")
    status, out = check(capsys, d)
    sys.modules.pop(name, None)
    assert status == 1
    assert out == [
        f"{d}:1: controller.{name}.Hasty: phase_timeout must be a positive, finite"
        " number of seconds, not 0 (the default of Hasty)"
    ]


def test_an_import_that_fails_says_why(tmp_path, capsys, monkeypatch):
    package = f"userpkg_{uuid.uuid4().hex[:8]}"
    (tmp_path / package / "sub").mkdir(parents=True)
    (tmp_path / package / "__init__.py").write_text("")
    (tmp_path / package / "sub" / "__init__.py").write_text(
        "raise ImportError('libfoo.so: cannot open shared object file')\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    d = write(tmp_path / "d.yaml", f"parts.{package}.sub.mod.Thing:\n    name: t\n")
    status, out = check(capsys, d)
    for key in [k for k in sys.modules if k.startswith(package)]:
        sys.modules.pop(key)
    assert status == 1
    assert out == [
        f"{d}:1: section type 'parts.{package}.sub.mod.Thing': importing "
        f"'{package}.sub' failed: ImportError: libfoo.so: cannot open shared "
        "object file"
    ]


# ---- process files: check and serve agree


@pytest.mark.parametrize(
    ("body", "line", "message"),
    [
        ("    name: hello\n", 1, "block.demo.Hello needs an 'mri' (text)"),
        ("", 1, "block.demo.Hello needs an 'mri' (text)"),
        (
            "    mir: HELLO\n",
            2,
            "block.demo.Hello needs an 'mri' (text) ('mir' may be a typo of it)",
        ),
    ],
)
def test_a_process_entry_without_mri_is_refused_by_check_and_serve_alike(
    tmp_path, capsys, body, line, message
):
    proc = tmp_path / "p.yaml"
    proc.write_text("block.demo.Hello:\n" + body)
    status, out = check(capsys, proc)
    assert (status, out) == (1, [f"{proc}:{line}: {message}"])
    assert main(["serve", str(proc)]) == 1
    assert f"{proc}:{line}: {message}\n" in capsys.readouterr().err

"""Looking up section kinds: explicit, entry point, dotted import path."""

import sys
import textwrap
import uuid

import pytest

from malcolm.config import registry
from malcolm.config.errors import ConfigError
from malcolm.config.registry import (
    check_kinds,
    known_kinds,
    lookup,
    register,
    unregister,
)
from malcolm.config.yamlsections import parse_sections


@pytest.fixture
def module(tmp_path, monkeypatch):
    """Write a throwaway module on sys.path; return its (unique) name."""
    name = f"cfgtest_{uuid.uuid4().hex}"
    (tmp_path / f"{name}.py").write_text(
        textwrap.dedent(
            """\
            from malcolm.parts import Part


            class MyPart(Part):
                class Inner(Part):
                    pass


            class NotAPart:
                pass


            NOT_CALLABLE = 42
            """
        )
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    yield name
    sys.modules.pop(name, None)


@pytest.fixture
def kinds():
    """Register kinds for one test only."""
    added = []

    def add(kind, factory):
        register(kind, factory)
        added.append(kind)

    yield add
    for kind in added:
        unregister(kind)


def test_explicit_registration(kinds):
    class Hello:
        pass

    kinds("parts.Hello", Hello)
    assert lookup("parts.Hello", "f.yaml", 3) is Hello
    assert "parts.Hello" in known_kinds()


def test_register_as_decorator():
    @register("parts.Decorated")
    class Decorated:
        pass

    try:
        assert lookup("parts.Decorated") is Decorated
        # registering the same factory again is harmless, another one is not
        register("parts.Decorated", Decorated)
        with pytest.raises(ValueError, match="already registered"):
            register("parts.Decorated", object)
    finally:
        unregister("parts.Decorated")


def test_register_rejects_bad_kinds():
    with pytest.raises(ValueError, match="invalid section kind"):
        register("nodot", object)


def test_dotted_import_path(module):
    factory = lookup(f"parts.{module}.MyPart", "f.yaml", 1)
    assert factory.__name__ == "MyPart"
    inner = lookup(f"parts.{module}.MyPart.Inner", "f.yaml", 1)
    assert inner.__name__ == "Inner"


def test_colon_import_path_from_yaml(module):
    (section,) = parse_sections(f"parts.{module}:MyPart:\n  name: x\n", "d.yaml")
    assert section.name == f"{module}:MyPart"
    assert lookup(section.kind, section.file, section.line).__name__ == "MyPart"


def test_dotted_path_errors(module):
    with pytest.raises(ConfigError, match=r"^f\.yaml:2: .*has no attribute 'Nope'"):
        lookup(f"parts.{module}.Nope", "f.yaml", 2)
    with pytest.raises(ConfigError, match="a value of type int, not a Part class"):
        lookup(f"parts.{module}.NOT_CALLABLE", "f.yaml", 2)


def test_broken_module_is_reported(tmp_path, monkeypatch):
    name = f"cfgbroken_{uuid.uuid4().hex}"
    (tmp_path / f"{name}.py").write_text("raise RuntimeError('boom')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(ConfigError, match=r"importing .* failed: RuntimeError: boom"):
        lookup(f"parts.{name}.Part", "f.yaml", 1)


def test_entry_point(tmp_path, monkeypatch, module):
    dist = tmp_path / "cfgtest_dist-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text(
        "Metadata-Version: 2.1\nName: cfgtest-dist\nVersion: 0.1\n"
    )
    (dist / "entry_points.txt").write_text(
        f"[{registry.ENTRY_POINT_GROUP}]\n"
        f"parts.EntryPart = {module}:MyPart\n"
        f"parts.BrokenEntry = {module}:Missing\n"
        f"parts.NotAPart = {module}:NotAPart\n"
        f"controller.PartAsController = {module}:MyPart\n"
    )
    assert lookup("parts.EntryPart", "f.yaml", 1).__name__ == "MyPart"
    assert "parts.EntryPart" in known_kinds()
    with pytest.raises(ConfigError, match="cannot load entry point"):
        lookup("parts.BrokenEntry", "f.yaml", 1)
    with pytest.raises(ConfigError) as info:
        lookup("parts.NotAPart", "f.yaml", 4)
    assert str(info.value) == (
        f"f.yaml:4: section type 'parts.NotAPart' (entry point '{module}:NotAPart')"
        f" names the class {module}.NotAPart, not a Part class (a section names a"
        " registered section type or a Part subclass)"
    )
    with pytest.raises(ConfigError, match="not a Controller class"):
        lookup("controller.PartAsController", "f.yaml", 1)


def test_unknown_kind_suggests_a_known_one(kinds):
    kinds("parts.PalettePart", object)
    with pytest.raises(ConfigError) as info:
        lookup("parts.PaletePart", "design.yaml", 12)
    assert str(info.value) == (
        "design.yaml:12: unknown section type 'parts.PaletePart' "
        "(did you mean 'parts.PalettePart'?)"
    )
    with pytest.raises(ConfigError, match=r"did you mean 'parts\.PalettePart'"):
        lookup("part.PalettePart", "design.yaml", 12)
    with pytest.raises(ConfigError, match=r"^d\.yaml:1: unknown section type"):
        lookup("parts.Nope", "d.yaml", 1)
    with pytest.raises(ConfigError, match="unknown section type 'parts.no.such.Mod'"):
        lookup("parts.no.such.Mod", "d.yaml", 1)


def test_check_kinds_reports_every_unknown_section(kinds):
    kinds("ca.Double", object)
    kinds("controller.Generic", object)
    sections = parse_sections(
        "init.String:\n  name: p\n"
        "ca.Double:\n  name: a\n"
        "ca.Dubble:\n  name: b\n"
        "block.ADCore.X:\n  name: c\n"
        "controller.Nope:\n"
        "parts.Nope:\n",
        "d.yaml",
    )
    with pytest.raises(ConfigError) as info:
        check_kinds(sections)
    assert [str(p) for p in info.value.problems] == [
        "d.yaml:5: unknown section type 'ca.Dubble' (did you mean 'ca.Double'?)",
        "d.yaml:9: unknown section type 'controller.Nope'",
        "d.yaml:10: unknown section type 'parts.Nope'",
    ]

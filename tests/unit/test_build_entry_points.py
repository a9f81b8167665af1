"""A part from another package, found through an entry point, used from YAML."""

import asyncio
import importlib
import sys
import textwrap
import uuid

import pytest

from malcolm.config.build import build_definition
from malcolm.config.errors import ConfigError
from malcolm.config.registry import ENTRY_POINT_GROUP, known_kinds

PART_SOURCE = '''
from malcolm.core import NumberMeta
from malcolm.parts import Part


class MyPart(Part):
    """Adds a writeable `gain` attribute."""

    def __init__(self, name, gain=1.0):
        super().__init__(name)
        self.gain = gain

    def setup(self, registrar):
        self.attr = registrar.add_attribute(
            "gain", NumberMeta("float64", "Amplifier gain", writeable=True), self.gain
        )
'''


@pytest.fixture
def site(tmp_path, monkeypatch):
    """An installed package `mypkg_<id>` with a `parts.MyPart` entry point."""
    package = f"mypkg_{uuid.uuid4().hex[:8]}"
    site = tmp_path / "site"
    (site / package).mkdir(parents=True)
    (site / package / "__init__.py").write_text(PART_SOURCE)
    dist = site / f"{package}-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text(
        f"Metadata-Version: 2.1\nName: {package}\nVersion: 0.1\n"
    )
    (dist / "entry_points.txt").write_text(
        f"[{ENTRY_POINT_GROUP}]\nparts.MyPart = {package}:MyPart\n"
    )
    monkeypatch.syspath_prepend(str(site))
    importlib.invalidate_caches()
    yield package
    sys.modules.pop(package, None)
    importlib.invalidate_caches()


def test_entry_point_part_builds_a_block(site, tmp_path):
    assert "parts.MyPart" in known_kinds()
    definition = tmp_path / "Amp.yaml"
    definition.write_text(
        textwrap.dedent(
            """\
            init.Float:
                name: gain
                default: 2.5

            parts.MyPart:
                name: amp
                gain: {gain}
            """
        )
    )
    process = build_definition(definition, {}, "AMP")
    controller = process.get_controller("AMP")
    part = controller.parts["amp"]
    assert type(part).__module__ == site and type(part).__name__ == "MyPart"
    block = process.get_block("AMP")
    assert block.gain.value == 2.5 and block.gain.meta.writeable

    async def scenario():
        await process.start()
        await process.put(["AMP", "gain"], 4)
        await process.stop()

    asyncio.run(asyncio.wait_for(scenario(), 10))
    assert block.gain.value == 4.0


def test_entry_point_part_keywords_are_checked(site, tmp_path):
    definition = tmp_path / "Amp.yaml"
    definition.write_text("parts.MyPart:\n    name: amp\n    gian: 3\n")
    with pytest.raises(ConfigError) as info:
        build_definition(definition, {}, "AMP")
    assert str(info.value) == (
        f"{definition}:3: parts.MyPart: unknown parameter 'gian' "
        "(MyPart takes name, gain) (did you mean 'gain'?)"
    )


def test_without_the_package_the_kind_is_unknown(tmp_path):
    definition = tmp_path / "Amp.yaml"
    definition.write_text("parts.MyPart:\n    name: amp\n")
    with pytest.raises(ConfigError, match=r"Amp.yaml:1: unknown section type"):
        build_definition(definition, {}, "AMP")

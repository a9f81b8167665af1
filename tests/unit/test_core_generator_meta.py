"""PointGeneratorMeta lives in core: runnable blocks round-trip through
from_dict, and a generator argument is data, never a file to open."""

import builtins

import pytest
from scanspec.specs import Line

from malcolm.controllers.runnable import RunnableController
from malcolm.core import BadValueError, PointGeneratorMeta, from_dict, serialize
from malcolm.core.builders import _common  # noqa: F401 (the split keeps helpers)
from malcolm.core.deltas import apply_changes
from malcolm.core.typeids import registered_typeids
from malcolm.demo import demo_process

from .scans import compound


def test_a_runnable_block_round_trips_through_from_dict():
    block = RunnableController("DET").block
    d = block.to_dict()
    assert d["configure"]["meta"]["takes"]["elements"]["generator"]["typeid"] == (
        "malcolm:core/PointGeneratorMeta:1.0"
    )
    again = from_dict(d, "DET")
    assert again.to_dict() == d
    assert isinstance(
        again.configure.meta.takes.elements["generator"], PointGeneratorMeta
    )


def test_every_demo_block_round_trips_through_from_dict():
    process = demo_process()
    for mri in process.mris:
        d = process.get_block(mri).to_dict()
        assert from_dict(d, mri).to_dict() == d, mri


def test_the_meta_checks_scans_as_before():
    meta = PointGeneratorMeta("scan")
    value = compound(("x", 3))
    assert meta.validate(value) == value
    assert meta.validate(Line("x", 0, 1, 3)) == Line("x", 0, 1, 3).serialize()
    with pytest.raises(BadValueError, match="a generator is required"):
        meta.validate(None)


def test_a_string_is_refused_without_opening_anything(monkeypatch, tmp_path):
    opened = []
    real_open = builtins.open

    def spy(file, *args, **kwargs):
        opened.append(file)
        return real_open(file, *args, **kwargs)

    secret = tmp_path / "secret.json"
    secret.write_text('{"typeid": "nope"}')
    monkeypatch.setattr(builtins, "open", spy)
    meta = PointGeneratorMeta("scan")
    for value in ["/etc/passwd", str(secret), secret]:
        with pytest.raises(BadValueError, match="never as the name of a file"):
            meta.validate(value)
    assert opened == []


def test_the_split_modules_keep_the_old_imports():
    assert serialize.apply_changes is apply_changes
    assert serialize.registered_typeids is registered_typeids
    assert "malcolm:core/PointGeneratorMeta:1.0" in registered_typeids()

"""``client.X`` with ``fullname: pva://HOST[:PORT]/MRI``: parsed, planned as
one mirror per remote block, refused at its line when malformed or when the
mri is taken; ``malcolm check`` connects to nothing."""

from __future__ import annotations

import pytest

from malcolm.cli import main
from malcolm.config import ConfigError
from malcolm.config.build import build_definition
from malcolm.config.remote import RemoteName, parse_remote
from malcolm.io.pva.client import RemoteBlock

TWO_CLIENTS = """\
controller.RunnableController:
    description: two parts on one remote detector

client.demo.Detector:
    name: DET
    fullname: pva://10.0.0.1/DET1
    part: RunnableChildPart

client.demo.Detector:
    name: SAME
    fullname: pva://10.0.0.1/DET1

block.demo.Counter:
    name: C
"""


def test_parse_remote():
    assert parse_remote("DET1") is None
    assert parse_remote("pva://h:5080/BL:DET") == RemoteName("h", 5080, "BL:DET")
    assert str(parse_remote("pva://h/X")) == "pva://h:5075/X"
    with pytest.raises(ValueError, match="unknown transport 'ca'"):
        parse_remote("ca://h/X")
    with pytest.raises(ValueError, match="names no block"):
        parse_remote("pva://h:5075")
    with pytest.raises(ValueError, match="port 'x' is not a port number"):
        parse_remote("pva://h:x/X")


def test_clients_of_one_remote_block_share_its_mirror(tmp_path):
    path = tmp_path / "B.yaml"
    path.write_text(TWO_CLIENTS)
    process = build_definition(path, mri="B")  # built, not started: no network
    assert process.mris == ["B:C", "DET1", "B"]
    mirror = process.get_controller("DET1")
    assert isinstance(mirror, RemoteBlock) and mirror.address == "10.0.0.1:5075"
    parts = process.get_controller("B").parts
    assert parts["DET"].mri == parts["SAME"].mri == "DET1"


def test_bad_remote_clients_are_refused_at_their_line(tmp_path):
    path = tmp_path / "B.yaml"
    path.write_text(
        TWO_CLIENTS.replace(
            "pva://10.0.0.1/DET1\n    part", "pva://h:x/DET1\n    part"
        ).replace("fullname: pva://10.0.0.1/DET1", "fullname: pva://10.0.0.2/B:C")
    )
    with pytest.raises(ConfigError) as e:
        build_definition(path, mri="B")
    assert [str(p) for p in e.value.problems] == [
        f"{path}:4: client 'DET': fullname 'pva://h:x/DET1': port 'x' is not a"
        " port number",
        f"{path}:9: client 'SAME': pva://10.0.0.2:5075/B:C would mirror block"
        " 'B:C' here, which is already a block of this process",
    ]


def test_check_does_not_connect(tmp_path, capsys):
    path = tmp_path / "B.yaml"
    path.write_text(TWO_CLIENTS)
    assert main(["check", str(path)]) == 0
    assert "1 file OK" in capsys.readouterr().err

"""``malcolm``'s parser is built without p4p; get/put/call/ls load it to run."""

from __future__ import annotations

import subprocess
import sys

from malcolm import cli_pva
from malcolm.io.pva import client_cli


def test_building_the_parser_imports_neither_p4p_nor_numpy():
    code = (
        "import sys; from malcolm.cli import build_parser; p = build_parser(); "
        "a = p.parse_args(['get', 'HELLO.greet']); "
        "print(sorted(m for m in ('p4p', 'numpy') if m in sys.modules), a.address)"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    )
    assert out.stdout.split() == ["[]", "127.0.0.1:5075"]


def test_the_arguments_agree_with_the_client():
    assert cli_pva.DEFAULT_ADDRESS == client_cli.DEFAULT_ADDRESS
    assert cli_pva.BLOCK_LIST_MRI == client_cli.BLOCK_LIST_MRI


def test_a_bad_address_is_one_line_and_status_1(capsys):
    from malcolm.cli import main

    assert main(["get", "HELLO", "--address", "no:port:here"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("malcolm get: ")

"""The arguments of ``malcolm get|put|call|ls`` (docs/pva-client.md).

Kept apart from :mod:`malcolm.io.pva.client_cli`, which does the work, so
that building the ``malcolm`` parser (every command, ``--help`` included)
does not import p4p and numpy: they load when one of these commands runs.
"""

from __future__ import annotations

import argparse
from typing import Any

__all__ = ["add_parsers"]

#: as :data:`malcolm.io.pva.client_cli.DEFAULT_ADDRESS` (a test keeps them equal)
DEFAULT_ADDRESS = "127.0.0.1:5075"
#: as :data:`malcolm.io.pva.client_cli.BLOCK_LIST_MRI`
BLOCK_LIST_MRI = "localhost"


def add_parsers(commands: Any) -> None:
    """Add ``get``, ``put``, ``call`` and ``ls`` to the ``malcolm`` parser."""

    def common(p: argparse.ArgumentParser) -> None:
        p.add_argument(
            "--address",
            default=DEFAULT_ADDRESS,
            metavar="HOST:PORT",
            help=f"the pvAccess server (default {DEFAULT_ADDRESS})",
        )
        p.add_argument("--json", action="store_true", help="print JSON")
        p.add_argument(
            "--timeout",
            type=float,
            default=5.0,
            metavar="SECONDS",
            help="give up after this long (default 5; a call: 0 waits for ever)",
        )

    get = commands.add_parser(
        "get",
        help="print a block or one field of it, over pvAccess",
        description="Print block MRI (every field), or its FIELD.",
    )
    get.add_argument("path", metavar="MRI[.FIELD]")
    common(get)
    get.set_defaults(func=lambda a: _run("get", a))

    put = commands.add_parser(
        "put",
        help="put a value to a field, over pvAccess",
        description="Put VALUE (JSON, or text) to MRI.FIELD; print it after.",
    )
    put.add_argument("path", metavar="MRI.FIELD")
    put.add_argument("value", metavar="VALUE")
    common(put)
    put.set_defaults(func=lambda a: _run("put", a))

    call = commands.add_parser(
        "call",
        help="call a method, over pvAccess",
        description=(
            "Call MRI.METHOD with arguments key=value (each value JSON, or "
            "text); print what it returns."
        ),
    )
    call.add_argument("path", metavar="MRI.METHOD")
    call.add_argument("args", metavar="KEY=VALUE", nargs="*")
    common(call)
    call.set_defaults(func=lambda a: _run("call", a))

    ls = commands.add_parser(
        "ls",
        help="list the blocks a pvAccess server offers",
        description=f"Print the blocks of the server ({BLOCK_LIST_MRI}.blocks).",
    )
    common(ls)
    ls.set_defaults(func=lambda a: _run("ls", a))


def _run(name: str, args: argparse.Namespace) -> int:
    from malcolm.io.pva.client_cli import run_command

    return run_command(name, args)

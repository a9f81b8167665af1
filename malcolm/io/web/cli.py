"""``--web-port`` for ``malcolm serve`` and ``malcolm demo``."""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING, TextIO

from malcolm.core import Process

if TYPE_CHECKING:
    from .lazy import LazyWebServer

DEFAULT_PORT = 8008


def web_port(text: str) -> int:
    """A TCP port number 0..65535 (for argparse)."""
    try:
        port = int(text)
    except ValueError:
        port = -1
    if not 0 <= port <= 65535:
        raise argparse.ArgumentTypeError(f"expected a port 0..65535, got {text!r}")
    return port


def add_web_port(parser: argparse.ArgumentParser) -> None:
    """Add ``--web-port`` (default 8008; 0 turns the web server off)."""
    parser.add_argument(
        "--web-port",
        type=web_port,
        default=DEFAULT_PORT,
        metavar="PORT",
        help=(
            f"serve the web GUI, WebSocket and REST on PORT (default {DEFAULT_PORT}; "
            "0: no web server)"
        ),
    )


async def start_if_asked(
    process: Process,
    port: int | None,
    prog: str,
    out: TextIO | None = None,
    err: TextIO | None = None,
) -> LazyWebServer | None:
    """Listen on ``port`` (None or 0: none) and print its address; the web
    server itself loads when the first client connects (:mod:`.lazy`). A port
    that cannot be bound is reported on ``err`` and serving goes on."""
    if not port:
        return None
    from .lazy import LazyWebServer

    try:
        server = LazyWebServer(process, port)
    except OSError as e:
        (err or sys.stderr).write(f"{prog}: no web server on port {port}: {e}\n")
        return None
    stream = out or sys.stdout
    stream.write(f"{prog}: web GUI at {server.url} (WebSocket {server.url}ws)\n")
    stream.flush()
    return server

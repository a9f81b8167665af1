"""``malcolm sim-zebra2``: serve a simulated PandA until Ctrl-C or SIGTERM."""

from __future__ import annotations

import argparse
import sys

from .layout import LAYOUTS


async def _serve(args: argparse.Namespace) -> int:
    import asyncio
    import signal

    from .server import serve_zebra2

    server = await serve_zebra2(
        args.host, args.control_port, args.data_port, args.layout
    )
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    print(
        f"zebra2 sim ({args.layout}): control {server.host}:{server.control_port}"
        f" data {server.host}:{server.data_port}",
        flush=True,
    )
    try:
        await stop.wait()
    finally:
        await server.close()
    return 0


def cmd_sim_zebra2(args: argparse.Namespace) -> int:
    """Serve the simulated box until signalled; 1 if it cannot start."""
    import asyncio

    try:
        return asyncio.run(_serve(args))
    except OSError as e:  # e.g. the port is taken
        print(f"malcolm sim-zebra2: {e}", file=sys.stderr)
        return 1


def add_parser(commands: argparse._SubParsersAction) -> None:
    """Add the ``sim-zebra2`` subcommand."""
    parser = commands.add_parser(
        "sim-zebra2",
        help="serve a simulated Zebra2/PandA box",
        description=(
            "Serve a simulated PandA (Zebra2) box on TCP: the control port answers "
            "as the recorded PandABlocks-server does, the data port streams PCAP "
            "captures.  Port 0 picks a free port."
        ),
    )
    parser.add_argument("--host", default="127.0.0.1", help="address to bind")
    parser.add_argument("--control-port", type=int, default=8888, metavar="PORT")
    parser.add_argument("--data-port", type=int, default=8889, metavar="PORT")
    parser.add_argument("--layout", choices=LAYOUTS, default="tier2")
    parser.set_defaults(func=cmd_sim_zebra2)

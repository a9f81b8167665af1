"""``malcolm sim-ioc``: serve the simulated beamline IOC."""

from __future__ import annotations

import argparse
from typing import Any

HELP = "serve the simulated beamline IOC (Channel Access) until stdin closes"


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--prefix", default="SIM", help="PV prefix of every record (default SIM)"
    )
    parser.add_argument(
        "--bench-blocks",
        type=int,
        default=0,
        metavar="N",
        help="also serve benchmarks/ca.py's records: N blocks of 20 PVs and a ticker",
    )


def run(args: argparse.Namespace) -> int:
    from .ioc import run as serve

    serve(args.prefix, args.bench_blocks)
    return 0


def add_parser(commands: Any) -> None:
    """Add ``sim-ioc`` to malcolm's subcommands."""
    parser = commands.add_parser("sim-ioc", help=HELP, description=HELP)
    configure(parser)
    parser.set_defaults(func=run)


def main() -> None:
    parser = argparse.ArgumentParser(prog="python -m malcolm.sim.beamline_ioc")
    configure(parser)
    raise SystemExit(run(parser.parse_args()))

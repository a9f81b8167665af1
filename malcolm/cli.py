"""The ``malcolm`` command line.

Each subcommand is one ``cmd_<name>(args) -> int`` function registered in
`build_parser` with ``set_defaults(func=...)``; add new subcommands the same
way.
"""

from __future__ import annotations

import argparse
import json
import sys


def cmd_points(args: argparse.Namespace) -> int:
    """Print every point of the scan described in ``args.file`` as JSON."""
    from malcolm.scan import scan_points

    try:
        points = scan_points(args.file)
        text = json.dumps(points.to_json(), allow_nan=False)
    except ValueError as e:  # GeneratorError, or a non-finite value for JSON
        print(f"{args.file}: {e}", file=sys.stderr)
        return 1
    print(text)
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every subcommand."""
    parser = argparse.ArgumentParser(
        prog="malcolm", description="Malcolm beamline-control tools."
    )
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")

    points = commands.add_parser(
        "points",
        help="print the points of a scan",
        description=(
            "Print the points of the scan described in FILE (a CompoundGenerator "
            "dict or a serialized scanspec Spec, as JSON or YAML) as JSON: axes, "
            "size, shape, and per axis positions, lower and upper bounds, plus "
            "duration."
        ),
    )
    points.add_argument("file", metavar="FILE", help="JSON or YAML file")
    points.set_defaults(func=cmd_points)

    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the command line; return the exit status."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as e:  # --help, or a usage error already reported
        return e.code if isinstance(e.code, int) else 2
    func = getattr(args, "func", None)
    if func is None:
        parser.print_usage(sys.stderr)
        print("malcolm: error: a COMMAND is required", file=sys.stderr)
        return 2
    return func(args)

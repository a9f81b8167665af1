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


def cmd_demo(args: argparse.Namespace) -> int:
    """Serve the built-in demo process (simulated hardware)."""
    import asyncio

    from malcolm.demo import serve_demo

    try:
        return asyncio.run(serve_demo(args.scan))
    except KeyboardInterrupt:
        print("malcolm demo: stopped", file=sys.stderr)
        return 0
    except Exception as e:  # no traceback reaches a user
        print(f"malcolm demo: {type(e).__name__}: {e}", file=sys.stderr)
        return 1


def cmd_graph(args: argparse.Namespace) -> int:
    """Print a state-machine model as Mermaid or Graphviz DOT text."""
    from malcolm.fsm import ModelError, load_model

    try:
        model = load_model(args.model)
    except ModelError as e:
        print(str(e), file=sys.stderr)
        return 1
    print(model.to_dot() if args.format == "dot" else model.to_mermaid())
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

    demo = commands.add_parser(
        "demo",
        help="serve the demo process",
        description=(
            "Serve the built-in demo process: HELLO, COUNTER, MOTOR:X, MOTOR:Y, "
            "DET1, DET2 and SCAN, all simulated."
        ),
    )
    demo.add_argument(
        "--scan", action="store_true", help="run a demo scan to the end, then exit"
    )
    demo.set_defaults(func=cmd_demo)

    graph = commands.add_parser(
        "graph",
        help="draw a state-machine model",
        description="Print MODEL (a name in models/ or a YAML path) as a diagram.",
    )
    graph.add_argument("model", metavar="MODEL")
    graph.add_argument("--format", choices=("mermaid", "dot"), default="mermaid")
    graph.set_defaults(func=cmd_graph)

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

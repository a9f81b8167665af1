"""The ``malcolm`` command line.

Each subcommand is one ``cmd_<name>(args) -> int`` function registered in
`build_parser` with ``set_defaults(func=...)``; add new subcommands the same
way.
"""

from __future__ import annotations

import argparse
import sys

from malcolm.sim.beamline_ioc import cli as sim_ioc_cli


def cmd_points(args: argparse.Namespace) -> int:
    """Print every point of the scan described in ``args.file`` as one JSON
    document, written a chunk at a time (memory does not grow with the scan)."""
    from malcolm.scan.files import GeneratorFileError, points_from_file

    try:
        points = points_from_file(args.file)
    except GeneratorFileError as e:
        print(e, file=sys.stderr)
        return 1
    try:
        for piece in points.iter_json():
            sys.stdout.write(piece)
    except ValueError as e:  # a non-finite value for JSON (refused when built)
        sys.stdout.write("\n")
        print(f"{args.file}: {e}", file=sys.stderr)
        return 1
    sys.stdout.write("\n")
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    """Serve the built-in demo process (simulated hardware)."""
    from malcolm.demo import demo_generator, serve_demo
    from malcolm.embed.loop import run as run_loop

    generator = demo_generator(duration=args.duration) if args.scan else None
    try:
        zebra2 = getattr(args, "zebra2", False)
        return run_loop(
            serve_demo(
                args.scan,
                generator=generator,
                freeze=True,
                pva_port=args.pva_port,
                zebra2=zebra2,
                web_port=args.web_port,
            )
        )
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


def cmd_check(args: argparse.Namespace) -> int:
    """Check definitions, process files, designs and models; 1 if any problem."""
    from malcolm.checker import run_check

    return run_check(args.files, args.search_path, args.kind, args.verbose)


def cmd_serve(args: argparse.Namespace) -> int:
    """Build the blocks of a process file and serve them until signalled."""
    import logging
    from pathlib import Path

    from malcolm.checker import default_search_path
    from malcolm.config import ConfigError
    from malcolm.core import long_lived
    from malcolm.embed import from_file, serve
    from malcolm.embed.loop import run as run_loop

    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.INFO,
        stream=sys.stderr,
        format="%(asctime)s %(levelname)s %(message)s",
    )
    if not args.verbose:  # the state-machine library narrates every callback
        logging.getLogger("transitions").setLevel(logging.WARNING)
    try:
        search_path = default_search_path(Path(args.file), args.search_path)
        with long_lived():  # the blocks live until the program ends
            process = from_file(args.file, search_path)
    except ConfigError as e:
        for problem in e.problems:
            print(problem, file=sys.stderr)
        n = len(e.problems)
        print(
            f"malcolm serve: {n} problem{'s' * (n != 1)}, nothing started",
            file=sys.stderr,
        )
        return 1
    except Exception as e:  # no traceback reaches a user
        print(f"malcolm serve: {type(e).__name__}: {e}", file=sys.stderr)
        return 1
    if args.ca_backend:  # e.g. soft: the ca.* attributes with no IOC
        from malcolm.io import use_backend

        try:
            use_backend(process, "ca", args.ca_backend)
        except ValueError as e:  # a name no backend is registered under
            print(f"malcolm serve: --ca-backend: {e}", file=sys.stderr)
            return 1

    def ready(p) -> None:
        print(f"malcolm serve: {len(p.mris)} blocks of {args.file} are running:")
        for mri in p.mris:
            print(f"  {mri:<20} {p.get_block(mri).state.value}")
        print("Reach them in this process by mri; stop with Ctrl-C or SIGTERM.")
        sys.stdout.flush()

    try:
        run_loop(
            serve(
                process,
                ready,
                freeze=True,
                pva_port=args.pva_port,
                web_port=args.web_port,
            )
        )
    except Exception as e:
        print(f"malcolm serve: {type(e).__name__}: {e}", file=sys.stderr)
        return 1
    print("malcolm serve: stopped", file=sys.stderr)
    return 0


def _seconds(text: str) -> float:
    """A positive, finite number of seconds (for argparse)."""
    import math

    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(
            f"expected a positive number of seconds, got {text!r}"
        )
    return value


def _port(text: str) -> int:
    """A TCP port number, 0 to 65535 (for argparse)."""
    try:
        port = int(text)
    except ValueError:
        port = -1
    if not 0 <= port <= 65535:
        raise argparse.ArgumentTypeError(f"expected a port 0-65535, got {text!r}")
    return port


def add_pva_port(parser: argparse.ArgumentParser) -> None:
    """``--pva-port`` of serve and demo (docs/pva.md)."""
    parser.add_argument(
        "--pva-port",
        type=_port,
        default=5075,
        metavar="PORT",
        help="serve the blocks over pvAccess on PORT (default 5075; 0: off)",
    )


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every subcommand."""
    from malcolm.io.web.cli import add_web_port

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
    demo.add_argument(
        "--duration",
        type=_seconds,
        default=0.05,
        metavar="SECONDS",
        help="seconds per point of the --scan (default 0.05)",
    )
    add_pva_port(demo)
    demo.add_argument(
        "--zebra2",
        action="store_true",
        help="add a simulated Zebra2 box, its manager ZEBRA2 and ZEBRA2:CAPTURE",
    )
    add_web_port(demo)
    demo.set_defaults(func=cmd_demo)

    graph = commands.add_parser(
        "graph",
        help="draw a state-machine model",
        description="Print MODEL (a name in models/ or a YAML path) as a diagram.",
    )
    graph.add_argument("model", metavar="MODEL")
    graph.add_argument("--format", choices=("mermaid", "dot"), default="mermaid")
    graph.set_defaults(func=cmd_graph)

    check = commands.add_parser(
        "check",
        help="check definitions, process files, designs and models",
        description=(
            "Check each FILE without starting anything: a state-machine model, a "
            "process file, a saved design or a block definition, told apart by "
            "content. Prints one 'file:line: message' per problem; exit status 1 "
            "if there is any."
        ),
    )
    check.add_argument("files", metavar="FILE", nargs="+")
    check.add_argument(
        "-I",
        "--search-path",
        metavar="DIR",
        action="append",
        default=[],
        help="look for definitions in DIR too (repeatable)",
    )
    check.add_argument(
        "--kind",
        choices=("definition", "process", "design", "model"),
        help="check every FILE as this kind instead of guessing",
    )
    check.add_argument(
        "-v", "--verbose", action="store_true", help="say how each file went"
    )
    check.set_defaults(func=cmd_check)

    serve = commands.add_parser(
        "serve",
        help="serve the blocks of a process file",
        description=(
            "Build every block of PROCESS (a process file), start them, log each "
            "state change, and run until SIGINT or SIGTERM. Definitions are "
            "looked for in malcolm/blocks, each -I DIR, then a blocks/ directory "
            "next to PROCESS or its parent directory."
        ),
    )
    serve.add_argument("file", metavar="PROCESS")
    serve.add_argument(
        "-I",
        "--search-path",
        metavar="DIR",
        action="append",
        default=[],
        help="look for definitions in DIR too (repeatable)",
    )
    serve.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    serve.add_argument(
        "--ca-backend",
        metavar="NAME",
        help="channel backend of ca.* attributes (default pyepics; soft: in memory)",
    )
    add_pva_port(serve)
    add_web_port(serve)
    serve.set_defaults(func=cmd_serve)

    sim_ioc_cli.add_parser(commands)
    from malcolm.sim.zebra2.cli import add_parser as add_sim_zebra2

    add_sim_zebra2(commands)
    from malcolm.beamline import add_parser as add_beamline

    add_beamline(commands)  # malcolm beamline (docs/beamline.md)

    from malcolm.cli_pva import add_parsers as add_pva_client

    add_pva_client(commands)  # get, put, call, ls (docs/pva-client.md)

    return parser


#: exit statuses for a run cut short, as a shell reports a signal's death
INTERRUPTED = 128 + 2  # SIGINT
BROKEN_PIPE = 128 + 13  # SIGPIPE


def main(argv: list[str] | None = None) -> int:
    """Run the command line; return the exit status.

    No traceback reaches a user: Ctrl-C outside the commands' own handling
    (during start-up, say) prints ``malcolm <command>: interrupted`` and
    returns 130; output to a pipe closed early (``malcolm graph | head``)
    ends quietly with 141.
    """
    for stream in (sys.stdout, sys.stderr):
        # a name the terminal cannot encode is escaped, never a crash
        if hasattr(stream, "reconfigure"):
            stream.reconfigure(errors="backslashreplace")
    command = "malcolm"
    try:
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
        command = f"malcolm {args.command}"
        status = func(args)
        sys.stdout.flush()  # a closed pipe is found here, not at exit
        return status
    except KeyboardInterrupt:
        print(f"{command}: interrupted", file=sys.stderr)
        return INTERRUPTED
    except BrokenPipeError:
        _discard_stdout()
        return BROKEN_PIPE


def _discard_stdout() -> None:
    """Point stdout at /dev/null, so that flushing it at exit cannot fail."""
    import os

    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError):  # no real file descriptor (captured)
        pass

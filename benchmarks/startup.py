"""Issue 8's start-up benchmarks, each in fresh interpreters.

    .venv/bin/python -m benchmarks.startup [--runs 10] [--blocks 1000]

- ``malcolm demo`` start to ready: the seconds from starting the command
  (``python -m malcolm demo``) until it prints that it is serving, median of
  ``--runs`` runs after one to warm the byte-code caches;
- ``--blocks`` blocks of 10 attributes (``ca.Double`` on soft channels, from
  one definition, listed in a process file): build and start, as ``malcolm
  serve`` does them (the blocks made under ``malcolm.core.long_lived``) and
  through the plain API (``build_process`` then ``Process.start``), median of
  three interpreters each; imports are not counted.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.table import Row, median, render

READY_LINE = "Serving until interrupted"
ROOT = Path(__file__).resolve().parents[1]  # where ``benchmarks`` is a package


def demo_ready_seconds() -> float:
    """Seconds from starting ``malcolm demo`` until it says it serves."""
    start = time.perf_counter()
    proc = subprocess.Popen(
        [sys.executable, "-m", "malcolm", "demo"],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    assert proc.stdout is not None
    try:
        for line in proc.stdout:
            if line.startswith(READY_LINE):
                return time.perf_counter() - start
        raise RuntimeError(f"malcolm demo ended without {READY_LINE!r}")
    finally:
        proc.send_signal(signal.SIGINT)
        proc.communicate(timeout=30)


def write_blocks(folder: Path, blocks: int, attributes: int = 10) -> Path:
    """A definition of ``attributes`` soft ``ca.Double``s and a process file
    of ``blocks`` blocks of it; returns the process file."""
    (folder / "bench").mkdir(parents=True, exist_ok=True)
    (folder / "bench" / "Box.yaml").write_text(
        "".join(
            f"ca.Double:\n    name: a{i}\n    pv: BOX:A{i}\n\n"
            for i in range(attributes)
        )
    )
    path = folder / "process.yaml"
    path.write_text(
        "".join(f"block.bench.Box:\n    mri: BOX{i}\n\n" for i in range(blocks))
    )
    return path


def build_and_start(blocks: int, served: bool) -> float:
    """In this interpreter: seconds to build and start ``blocks`` blocks."""
    import contextlib

    from malcolm.config.build import build_process
    from malcolm.core import long_lived

    with tempfile.TemporaryDirectory() as tmp:
        path = write_blocks(Path(tmp), blocks)

        async def main() -> float:
            start = time.perf_counter()
            with long_lived() if served else contextlib.nullcontext():
                process = build_process(path, [Path(tmp)])
                await process.start()
            elapsed = time.perf_counter() - start
            states = {process.get_block(m).state.value for m in process.mris}
            assert len(process.mris) == blocks and states == {"Ready"}, states
            await process.stop()
            return elapsed

        return asyncio.run(main())


def blocks_seconds(blocks: int, served: bool) -> float:
    """:func:`build_and_start` in a fresh interpreter."""
    out = subprocess.run(
        [sys.executable, "-m", "benchmarks.startup", "--child", str(blocks)]
        + (["--served"] if served else []),
        capture_output=True,
        text=True,
        check=True,
        cwd=ROOT,
        # the blocks' ca.Double attributes live in memory (the soft backend):
        # this measures building and starting blocks, not connecting 10,000
        # PVs to an IOC that is not there (the ca default is pyepics)
        env=dict(os.environ, MALCOLM_CA_BACKEND="soft"),
    )
    return float(json.loads(out.stdout.splitlines()[-1]))


def rows(runs: int, blocks: int, interpreters: int = 3) -> list[Row]:
    """Measure every case; the table's rows."""
    demo_ready_seconds()  # warm the byte-code caches
    ready = median([demo_ready_seconds() for _ in range(runs)])
    served = median([blocks_seconds(blocks, True) for _ in range(interpreters)])
    plain = median([blocks_seconds(blocks, False) for _ in range(interpreters)])
    what = f"{blocks} blocks x 10 attributes, build+start"
    scale = "" if blocks == 1000 else "; target for 1000"
    return [
        Row(
            "malcolm demo, start to ready",
            ready,
            "s",
            "<= 0.5 s",
            "0.78 s",
            f"median of {runs}; was 1.40 s",
        ),
        Row(
            f"{what} (as malcolm serve)",
            served,
            "s",
            "<= 2 s",
            "4.6 s",
            f"median of {interpreters}; was 6.6 s{scale}",
        ),
        Row(
            f"{what} (plain API)",
            plain,
            "s",
            "-",
            "4.6 s",
            f"median of {interpreters}; no long_lived()",
        ),
    ]


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=10)
    parser.add_argument("--blocks", type=int, default=1000)
    parser.add_argument("--child", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--served", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child is not None:
        print(json.dumps(build_and_start(args.child, args.served)))
        return
    print(render(rows(args.runs, args.blocks)))


if __name__ == "__main__":
    main()

"""Helpers of the ZebraManager tests: the block on the simulated box, and
the raw file read by another process (so it must be closed)."""

from __future__ import annotations

import asyncio
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

from malcolm.config.build import build_definition
from malcolm.core import Process

from .conftest import SimBox

MRI = "BL:ZEBRA"

READ = """
import json, sys
import h5py
with h5py.File(sys.argv[1], "r") as f:
    print(json.dumps({name: f[name][()].tolist() for name in f}))
"""


def zebra_process(sim: SimBox, **params: Any) -> Process:
    """A process with a ZebraManager ``BL:ZEBRA`` on ``sim`` (not started)."""
    process = Process("zebramgr")
    build_definition(
        "zebra2.ZebraManager",
        {
            "host": sim.host,
            "control_port": sim.control_port,
            "data_port": sim.data_port,
            **params,
        },
        MRI,
        process=process,
    )
    return process


def read_elsewhere(path: Path) -> dict[str, list[Any]]:
    """Every dataset of ``path``, read by another Python process: it fails
    if the file is still open for writing."""
    out = subprocess.run(
        [sys.executable, "-c", READ, str(path)],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout)


async def wait_for(block: Any, field: str, predicate: Any, timeout: float = 20) -> Any:
    """Until ``block[field]``'s value satisfies ``predicate``; the value."""
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout
    while not predicate(block[field].value):
        assert loop.time() < deadline, f"{field} is still {block[field].value!r}"
        await asyncio.sleep(0.01)
    return block[field].value

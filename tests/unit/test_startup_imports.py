"""Start-up loads only what every path needs (issue 8): building and starting
the demo process imports neither the scan engine nor what it needs (numpy,
scanspec), which are loaded when a scan is first checked, nor the package
metadata reader that finds section types by entry point (only a kind that is
not built in needs it)."""

from __future__ import annotations

import json
import subprocess
import sys

SCRIPT = """
import asyncio, json, sys
from malcolm.demo import demo_process

async def main():
    process = demo_process()
    await process.start()
    await process.stop()

asyncio.run(main())
loaded = sorted(
    m for m in sys.modules
    if m.split(".")[0] in ("numpy", "scanspec", "pydantic")
    or m.startswith("malcolm.scan") or m == "importlib.metadata"
)
print(json.dumps(loaded))
"""


def loaded_by(script: str) -> list[str]:
    out = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, check=True
    )
    return json.loads(out.stdout.splitlines()[-1])


def test_the_demo_starts_without_the_scan_engine() -> None:
    assert loaded_by(SCRIPT) == []


def test_a_scan_loads_it_when_first_checked() -> None:
    script = SCRIPT.replace(
        "    await process.stop()",
        "    from malcolm.demo import demo_generator\n"
        "    scan = {'generator': demo_generator()}\n"
        "    await process.post(['SCAN', 'validate'], scan)\n"
        "    await process.stop()",
    )
    loaded = loaded_by(script)
    assert "malcolm.scan" in loaded and "numpy" in loaded

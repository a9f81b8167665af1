"""``malcolm demo --zebra2``: a simulated Zebra2 box next to the demo.

:func:`start_demo_zebra2` starts the simulator (``malcolm.sim.zebra2``,
tier 2) in the demo's own loop on free ports of 127.0.0.1, and adds two
blocks to the process (before it starts): ``ZEBRA2``, a ``zebra2.Manager``
on it (children ``ZEBRA2:PCOMP1``...), and ``ZEBRA2:CAPTURE``, a
``zebra2.Capture``. It returns the server (``host``, ``control_port``,
``data_port``, ``async close()``).
"""

from __future__ import annotations

from typing import Any

from malcolm.core import Process

__all__ = ["DEMO_ZEBRA2_MRI", "start_demo_zebra2"]

DEMO_ZEBRA2_MRI = "ZEBRA2"


async def start_demo_zebra2(process: Process, host: str = "127.0.0.1") -> Any:
    """Serve a simulated box and add its manager and capture blocks."""
    from malcolm.config.build import build_definition
    from malcolm.sim.zebra2 import serve_zebra2

    server = await serve_zebra2(host, 0, 0, "tier2")
    try:
        ports = {
            "host": server.host,
            "control_port": server.control_port,
            "data_port": server.data_port,
        }
        build_definition("zebra2.Manager", ports, DEMO_ZEBRA2_MRI, process=process)
        build_definition(
            "zebra2.Capture", ports, f"{DEMO_ZEBRA2_MRI}:CAPTURE", process=process
        )
    except Exception:
        await server.close()
        raise
    return server

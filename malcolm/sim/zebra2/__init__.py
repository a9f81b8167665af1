"""A simulated Zebra2 / PandA box: control port (8888) and data port (8889).

Entry points (stable; other code and tests use them)::

    from malcolm.sim.zebra2 import serve_zebra2

    server = await serve_zebra2(
        host="127.0.0.1", control_port=8888, data_port=8889, layout="tier2"
    )
    ...  # server.host, server.control_port, server.data_port (0 = any port)
    await server.close()

and on the command line ``malcolm sim-zebra2 [--host H] [--control-port P]
[--data-port P] [--layout tier1|tier2]``.  ``layout`` is one of the two
recorded boxes of /work/shared/zebra2 (their introspection ships in
``data/``).  ``serve_zebra2(..., clock=ManualClock())`` lets a test step the
simulated time itself.  What is and is not simulated: docs/zebra2-sim.md.
"""

from __future__ import annotations

import importlib
from typing import Any

#: where each exported name lives; loaded when first used, so that the
#: command line (which only needs LAYOUTS for sim-zebra2's options) does not
#: import the server and numpy for every command
_WHERE = {
    "LAYOUTS": ".layout",
    "Layout": ".layout",
    "load_layout": ".layout",
    "Zebra2Server": ".server",
    "serve_zebra2": ".server",
    "ManualClock": ".simulation",
    "RealClock": ".simulation",
}


def __getattr__(name: str) -> Any:
    where = _WHERE.get(name)
    if where is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(where, __name__), name)


__all__ = [
    "LAYOUTS",
    "Layout",
    "ManualClock",
    "RealClock",
    "Zebra2Server",
    "load_layout",
    "serve_zebra2",
]

"""Make a process's blocks without the cyclic garbage collector rescanning them.

Building and starting a thousand blocks makes some 400,000 objects that live
as long as the process. CPython's collector scans every tracked object in a
full collection, and runs one each time the number of long-lived objects has
grown by a quarter: seven full collections while such a process is built and
started (over a second of this machine's time), and later ones that stall
the loop for a tenth of a second each while the blocks are served.

``with long_lived():`` pauses the collector while the objects are made and,
on leaving without an error, moves every object then alive to the permanent
generation (:func:`gc.freeze`), which the collector no longer scans. The
blocks are still freed by reference counting when they go; only garbage
*cycles* among frozen objects stay until :func:`gc.unfreeze`. That is the
right trade for a server (``malcolm serve``, ``malcolm demo``), which builds
its blocks once and keeps them; a program that builds and drops many
processes need not use it.
"""

from __future__ import annotations

import gc
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["long_lived"]


@contextmanager
def long_lived() -> Iterator[None]:
    """Pause the cyclic collector inside; freeze what is alive on leaving.

    The collector is enabled again on leaving, also after an error (which
    freezes nothing), if it was enabled on entering.
    """
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
        gc.freeze()
    finally:
        if enabled:
            gc.enable()

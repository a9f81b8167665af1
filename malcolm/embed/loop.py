"""The event loop malcolm's own processes run on.

``malcolm serve``, ``malcolm demo``, the beamline and :class:`ThreadedProcess`
make their loop here. It is uvloop's where uvloop is installed (a dependency
on Linux and macOS), else the standard library's: both are asyncio loops,
and malcolm runs the same on either (its tests run on both).

Why uvloop: every request a transport serves reaches the loop from a library
thread (p4p's, libca's) through ``loop.call_soon_threadsafe``, and the loop's
wake-up for it is part of every round trip a client sees. uvloop's is done
in C (libuv) rather than in ``asyncio``'s Python ``_run_once``; on this
project's benchmark it took the hop from p4p's thread to the loop and back
from about 15% of a bare p4p method call round trip to about 10%
(``benchmarks.pva``'s "bare, answered on an asyncio loop" row).

``MALCOLM_LOOP=asyncio`` in the environment selects the standard library's
loop, ``MALCOLM_LOOP=uvloop`` requires uvloop. Code that embeds malcolm on a
loop of its own (``async with running(process)``) keeps that loop.

One difference to know: uvloop's clock (``loop.time()``, and so the loop's
timers) counts whole milliseconds, where asyncio's has the monotonic clock's
resolution. Nothing in malcolm waits or paces on less than a millisecond
(a scan's points are paced against their accumulated deadlines, see
:mod:`malcolm.parts.pacing`, so rounding does not add up over a scan).
"""

from __future__ import annotations

import asyncio
import os
from collections.abc import Callable, Coroutine
from typing import Any, TypeVar

__all__ = ["LOOP_ENV", "loop_name", "new_event_loop", "run"]

#: the environment variable that chooses the loop: "uvloop" or "asyncio"
LOOP_ENV = "MALCOLM_LOOP"

T = TypeVar("T")


class LoopChoiceError(RuntimeError):
    """``MALCOLM_LOOP`` names a loop that is unknown or not installed."""


def _uvloop_factory() -> Callable[[], asyncio.AbstractEventLoop] | None:
    try:
        import uvloop
    except ImportError:
        return None
    return uvloop.new_event_loop


def loop_name() -> str:
    """``"uvloop"`` or ``"asyncio"``: what :func:`new_event_loop` makes
    (``MALCOLM_LOOP`` if set, else uvloop's where installed)."""
    chosen = os.environ.get(LOOP_ENV, "").strip().lower()
    if chosen not in ("", "uvloop", "asyncio"):
        raise LoopChoiceError(
            f"{LOOP_ENV}={chosen!r}: expected 'uvloop' or 'asyncio' (or unset)"
        )
    if chosen == "asyncio":
        return "asyncio"
    if _uvloop_factory() is not None:
        return "uvloop"
    if chosen == "uvloop":
        raise LoopChoiceError(
            f"{LOOP_ENV}=uvloop, but uvloop is not installed"
            " (pip install uvloop, or unset it for asyncio's loop)"
        )
    return "asyncio"


def new_event_loop() -> asyncio.AbstractEventLoop:
    """A new event loop of the kind :func:`loop_name` says."""
    if loop_name() == "uvloop":
        factory = _uvloop_factory()
        assert factory is not None
        return factory()
    return asyncio.new_event_loop()


def run(main: Coroutine[Any, Any, T]) -> T:
    """``asyncio.run(main)`` on a loop of :func:`new_event_loop`'s."""
    with asyncio.Runner(loop_factory=new_event_loop) as runner:
        return runner.run(main)

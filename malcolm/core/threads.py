"""One asyncio loop owns block state: the path other threads take to it, and
the guard that catches changes made anywhere else.

A started :class:`~malcolm.core.Process` owns its blocks from its loop's
thread. Code running in any other thread (a library's callback thread, such
as pyepics' or p4p's, or a worker thread of the caller's own) reaches the
loop through :func:`call_threadsafe` (or ``Process.call_threadsafe``), which
runs a function there and returns a :class:`concurrent.futures.Future` of
its result.

Plain ``def`` hook functions run in worker threads that may *wait* for the
loop: their changes to block state are handed to the loop and the thread
waits for them (:func:`marshalling`). Any other change made off the loop
thread is a bug: with the **loop guard** on (:func:`enable_loop_guard`, or
the environment variable ``MALCOLM_LOOP_GUARD=1``) it raises
:class:`OffLoopError` before anything changes.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import inspect
import os
import threading
from collections import deque
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

from .errors import MalcolmError

__all__ = [
    "LoopOwner",
    "OffLoopError",
    "call_threadsafe",
    "enable_loop_guard",
    "loop_guard_enabled",
    "marshalling",
]

_guard = os.environ.get("MALCOLM_LOOP_GUARD", "").strip() not in ("", "0")
_local = threading.local()

#: the messages of the last OffLoopErrors raised (also those that code
#: swallowed, e.g. in a subscriber callback), newest last
guard_trips: deque[str] = deque(maxlen=100)

#: ``submit(func, *args)`` runs ``func(*args)`` on the loop and returns its
#: result, blocking the calling thread (see :func:`marshalling`)
Submit = Callable[..., Any]


class OffLoopError(MalcolmError, RuntimeError):
    """Block state was changed from a thread other than its process's loop."""


def enable_loop_guard(on: bool = True) -> None:
    """Turn the loop guard on (or off) for the whole Python process."""
    global _guard
    _guard = bool(on)


def loop_guard_enabled() -> bool:
    """Whether changes off the loop thread raise OffLoopError."""
    return _guard


def call_threadsafe(
    loop: asyncio.AbstractEventLoop, func: Callable[..., Any], *args: Any
) -> concurrent.futures.Future[Any]:
    """Run ``func(*args)`` on ``loop``; from any thread, including the loop's.

    If ``func`` returns an awaitable it is awaited on the loop. Returns a
    future of the result (or of the exception): ``.result()`` waits for it
    in another thread; cancelling it cancels the awaitable. On the loop's own
    thread ``func`` runs at once (so a plain function's future is already
    done: never block on it there). Nothing is created before the loop runs
    ``func``, so a loop that stops first leaves no coroutine unawaited.
    """
    fut: concurrent.futures.Future[Any] = concurrent.futures.Future()

    def settle(result: Any = None, error: BaseException | None = None) -> None:
        if not fut.set_running_or_notify_cancel():
            return  # cancelled by whoever waited
        if error is not None:
            fut.set_exception(error)
        else:
            fut.set_result(result)

    def run() -> None:
        if fut.cancelled():
            return
        try:
            result = func(*args)
        except BaseException as e:  # handed to whoever waits for the future
            settle(error=e)
            return
        if not inspect.isawaitable(result):
            settle(result)
            return
        task = asyncio.ensure_future(result)

        def copy(t: asyncio.Future[Any]) -> None:
            if t.cancelled():
                fut.cancel()
            else:
                settle(t.result() if t.exception() is None else None, t.exception())

        def on_cancel(f: concurrent.futures.Future[Any]) -> None:
            if f.cancelled() and not loop.is_closed():
                loop.call_soon_threadsafe(task.cancel)

        task.add_done_callback(copy)
        fut.add_done_callback(on_cancel)

    if _on_loop_thread(loop):
        run()
    else:
        loop.call_soon_threadsafe(run)
    return fut


def _on_loop_thread(loop: asyncio.AbstractEventLoop) -> bool:
    try:
        return asyncio.get_running_loop() is loop
    except RuntimeError:
        return False


@contextmanager
def marshalling(loop: asyncio.AbstractEventLoop, submit: Submit) -> Iterator[None]:
    """In this block, this thread's changes to state owned by ``loop`` are run
    there by ``submit(func, *args)``, which blocks until they are done.

    Only for threads the loop never waits for (hook worker threads): a thread
    the loop is blocked on would wait for ever.
    """
    previous = getattr(_local, "marshal", None)
    _local.marshal = (loop, submit)
    try:
        yield
    finally:
        _local.marshal = previous


class LoopOwner:
    """The loop (and its thread) that owns a process's blocks once started."""

    def __init__(self, loop: asyncio.AbstractEventLoop, name: str = "") -> None:
        self.loop = loop
        self.name = name
        self.thread = threading.get_ident()

    def here(self) -> bool:
        """Whether the calling thread is the owning loop's thread."""
        return threading.get_ident() == self.thread

    def elsewhere(
        self, what: str, func: Callable[..., Any], *args: Any
    ) -> tuple[bool, Any]:
        """Deal with ``func(*args)`` (changing ``what``) called off the loop.

        Returns ``(True, result)`` if it was run on the loop for a thread that
        may wait (see :func:`marshalling`), ``(False, None)`` if the caller
        should go ahead where it is (guard off). With the guard on, raises
        OffLoopError naming ``what`` and the thread.
        """
        marshal = getattr(_local, "marshal", None)
        if marshal is not None and marshal[0] is self.loop and self.loop.is_running():
            return True, marshal[1](func, *args)
        if _guard:
            message = (
                f"{what} was changed from thread"
                f" {threading.current_thread().name!r}, not the loop thread of"
                f" process {self.name!r}: hand the change to the loop with"
                " process.call_threadsafe() (docs/channels.md)"
            )
            guard_trips.append(message)
            raise OffLoopError(message)
        return False, None

"""Puts and method calls of the pvAccess server, run on the process's loop.

p4p calls a SharedPV's ``put`` and ``rpc`` handlers in its own thread.
:class:`LoopSharedPV` hands each to the loop instead, as
``p4p.server.asyncio`` does (``SharedPV._exec`` and
``loop.call_soon_threadsafe``): one hop, with nothing built in p4p's thread
but the hand-over, so the handler itself runs on the loop (the rule of
docs/channels.md: block state changes there only).

There, :func:`start_op` runs the operation's coroutine as a Task whose
first step is taken at once, in the handler (an *eager* start, what
``asyncio.eager_task_factory`` does from Python 3.12): a put or call that
never waits (most of them) has answered the client before the handler
returns, with no turn of the loop in between; one that waits goes on in
its Task as any other. The step runs with the Task as the current task,
in the Task's context, so ``asyncio.current_task()``, cancellation and
context variables behave as in a plain Task.
"""

from __future__ import annotations

import asyncio
import contextvars
import logging
from collections.abc import Callable, Coroutine, Generator
from typing import Any

from p4p.server.raw import SharedPV

__all__ = ["LoopSharedPV", "error_text", "start_op"]

log = logging.getLogger(__name__)

# asyncio's own bookkeeping of the current task (what Task.__step does);
# without it (another Python) the first step waits for the Task's turn
_enter_task: Callable[..., None] | None = getattr(asyncio.tasks, "_enter_task", None)
_leave_task: Callable[..., None] | None = getattr(asyncio.tasks, "_leave_task", None)


def error_text(e: BaseException) -> str:
    """An error as a client sees it: ``"<ExceptionType>: <message>"``."""
    return f"{type(e).__name__}: {e}"


class LoopSharedPV(SharedPV):
    """A p4p SharedPV whose put and rpc handlers run on ``loop``.

    Connection callbacks (``onFirstConnect``, ``onLastDisconnect``) stay in
    p4p's thread: the handler's own (cheap, thread-safe) bookkeeping."""

    def __init__(self, loop: asyncio.AbstractEventLoop, handler: Any) -> None:
        self._loop = loop
        super().__init__(handler=handler)

    def _exec(self, op: Any, method: Any, *args: Any) -> None:  # p4p's hook
        if op is None:
            super()._exec(op, method, *args)
            return
        try:
            self._loop.call_soon_threadsafe(_run_handler, op, method, args)
        except RuntimeError as e:  # the loop is closed: the server is stopping
            op.done(error=error_text(e))


def _run_handler(op: Any, method: Any, args: tuple[Any, ...]) -> None:
    """On the loop: ``method(*args)``; an error it raises goes to the client."""
    try:
        method(*args)
    except Exception as e:
        log.exception("pva handler %r", method)
        op.done(error=error_text(e))


def start_op(
    op: Any, coro: Coroutine[Any, Any, None], tasks: set[asyncio.Task[Any]]
) -> None:
    """Run ``coro`` (which answers ``op`` when it succeeds) on the running
    loop, its first step now if no task is running (a loop callback, as the
    handlers are); an Exception it raises is ``op``'s error.
    While it waits, its Task is in ``tasks`` (cancelled when the server
    closes)."""
    loop = asyncio.get_running_loop()
    step = _EagerStep(op, coro)
    context = contextvars.copy_context()  # the Task's: the step runs in it
    task = loop.create_task(step, context=context)  # type: ignore[arg-type]
    eager = _enter_task is not None and _leave_task is not None
    if eager and asyncio.current_task(loop) is None:  # as from p4p's hand-over
        _enter_task(loop, task)
        try:
            context.run(step.first)
        finally:
            _leave_task(loop, task)
    if not step.ended:  # it waits: close() of the server cancels it
        tasks.add(task)
        task.add_done_callback(tasks.discard)


_UNSTARTED = object()


class _EagerStep:
    """What a Task runs for a coroutine whose first step :meth:`first` took
    before the Task's turn: the Task's first ``send`` gives back what that
    step gave (the future it waits on, or its end); later sends and throws
    go straight to the coroutine. An Exception the coroutine raises is
    ``op``'s error, and the step ends as the coroutine would have returned.
    (The coroutine protocol, so that ``asyncio.Task`` takes it.)"""

    __slots__ = ("coro", "op", "_first")

    def __init__(self, op: Any, coro: Coroutine[Any, Any, Any]) -> None:
        self.coro = coro
        self.op = op
        self._first: Any = _UNSTARTED

    @property
    def ended(self) -> bool:
        """Whether the first step (taken) was the coroutine's last."""
        return isinstance(self._first, tuple) and self._first[0] == "raise"

    def first(self) -> None:
        try:
            self._first = ("yield", self._resume(self.coro.send, None))
        except BaseException as e:  # its end (StopIteration) or its error
            self._first = ("raise", e)

    def _resume(self, func: Callable[..., Any], *args: Any) -> Any:
        try:
            return func(*args)
        except StopIteration:
            raise
        except Exception as e:  # the client's error; the operation ends
            self.op.done(error=error_text(e))
            raise StopIteration from None

    def send(self, value: Any) -> Any:
        first, self._first = self._first, None
        if first is None or first is _UNSTARTED:
            return self._resume(self.coro.send, value)
        kind, what = first
        if kind == "raise":
            raise what
        return what

    def throw(self, *exc: Any) -> Any:
        self._first = None
        return self._resume(self.coro.throw, *exc)

    def close(self) -> None:
        self._first = None
        self.coro.close()

    def __next__(self) -> Any:
        return self.send(None)

    def __iter__(self) -> _EagerStep:
        return self

    def __await__(self) -> Generator[Any, None, Any]:
        return self  # type: ignore[return-value]

"""Puts and method calls of the pvAccess server, run on the process's loop.

p4p calls a SharedPV's ``put`` and ``rpc`` handlers in its own thread.
:class:`LoopSharedPV` hands each to the loop instead, with
``loop.call_soon_threadsafe`` as ``p4p.server.asyncio`` does: one hop, with
nothing built in p4p's thread but the hand-over (not even p4p's own wrapper
of the handler), so the handler itself runs on the loop (the rule of
docs/channels.md: block state changes there only).

There, :class:`OpRunner` takes the operation's first step at once, in the
handler (an *eager* start, what ``asyncio.eager_task_factory`` does from
Python 3.12): a put or call that never waits (most of them) has answered
the client before the handler returns, with no turn of the loop in
between; one that waits goes on in a Task as any other.

The first step runs as a step of the runner's *standing* Task, current
and in that Task's context, so ``asyncio.current_task()``, cancellation
and context variables behave as in a plain Task. An operation that ends
in that step leaves the standing Task waiting for the next one: no Task
is made, scheduled, stepped and finished per operation (on this machine
that bookkeeping, cold between two client requests, was half of what a
served call and put added to the round trip). An operation that waits
keeps the standing Task as its own (it goes on in it; a new standing
Task is made), so the Task a waiting operation saw in its first step is
the one that runs, and can be cancelled, to its end. An operation that
ends at once must therefore not keep its ``current_task()`` to use after
it returned (none in malcolm does: they compare it, or use it while they
run); one that leaves a context variable set ends the standing Task (the
next operation gets a clean context).
"""

from __future__ import annotations

import asyncio
import contextvars
import logging
from collections.abc import Callable, Coroutine, Generator
from typing import Any

from p4p.server.raw import SharedPV
from p4p.server.raw import _SharedPV as _RawSharedPV

__all__ = ["LoopSharedPV", "OpRunner", "error_text", "start_op"]

log = logging.getLogger(__name__)

# asyncio's own bookkeeping of the current task (what Task.__step does);
# without it (another Python) the first step waits for the Task's turn
_enter_task: Callable[..., None] | None = getattr(asyncio.tasks, "_enter_task", None)
_leave_task: Callable[..., None] | None = getattr(asyncio.tasks, "_leave_task", None)
# loop -> its current task (what asyncio.current_task reads), read in line
_current_tasks: dict[Any, Any] | None = getattr(asyncio.tasks, "_current_tasks", None)


def error_text(e: BaseException) -> str:
    """An error as a client sees it: ``"<ExceptionType>: <message>"``."""
    return f"{type(e).__name__}: {e}"


class LoopSharedPV(SharedPV):
    """A p4p SharedPV whose put and rpc handlers run on ``loop``.

    p4p's thread hands a put or call over in one step, with nothing built
    there but the hand-over: the PV's C++ side calls :class:`_LoopHandler`,
    in place of p4p's own wrapper (which logged each operation at debug
    level, wrapped a put's operation for a ``nt`` this server has not, and
    went through ``_exec``). Connection callbacks (``onFirstConnect``,
    ``onLastDisconnect``) stay in p4p's thread: the handler's own (cheap,
    thread-safe) bookkeeping."""

    def __init__(self, loop: asyncio.AbstractEventLoop, handler: Any) -> None:
        self._loop = loop
        # what p4p's SharedPV.__init__ sets, with this module's hand-over
        self.nt = None
        self._handler = handler
        self._wrap = self._unwrap = _same
        self._whandler = _LoopHandler(self, loop, handler)
        _RawSharedPV.__init__(self, self._whandler, None)


def _same(value: Any) -> Any:
    return value


class _LoopHandler:
    """What a :class:`LoopSharedPV`'s C++ side calls (in p4p's threads)."""

    __slots__ = ("pv", "real", "call")

    def __init__(self, pv: SharedPV, loop: asyncio.AbstractEventLoop, real: Any):
        self.pv = pv
        self.real = real
        self.call = loop.call_soon_threadsafe

    def onFirstConnect(self) -> None:  # noqa: N802 (p4p's name)
        try:
            self.real.onFirstConnect(self.pv)
        except Exception:
            log.exception("pva onFirstConnect %r", self.pv)

    def onLastDisconnect(self) -> None:  # noqa: N802
        try:
            self.real.onLastDisconnect(self.pv)
        except Exception:
            log.exception("pva onLastDisconnect %r", self.pv)

    def put(self, op: Any) -> None:
        try:
            self.call(_run_handler, op, self.real.put, (self.pv, op))
        except RuntimeError as e:  # the loop is closed: the server is stopping
            op.done(error=error_text(e))

    def rpc(self, op: Any) -> None:
        try:
            self.call(_run_handler, op, self.real.rpc, (self.pv, op))
        except RuntimeError as e:
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
    loop in a Task of its own, its first step now if no task is running (a
    loop callback, as the handlers are); an Exception it raises is ``op``'s
    error. While it waits, its Task is in ``tasks``. (:class:`OpRunner`
    does the same without a Task per operation that ends at once.)"""
    loop = asyncio.get_running_loop()
    step = _EagerStep(op, coro)
    context = contextvars.copy_context()  # the Task's: the step runs in it
    task = loop.create_task(step, context=context)  # type: ignore[arg-type]
    if _EAGER and asyncio.current_task(loop) is None:  # as from p4p's hand-over
        _enter_task(loop, task)  # type: ignore[misc]
        try:
            context.run(step.first)
        finally:
            _leave_task(loop, task)  # type: ignore[misc]
    if not step.ended:  # it waits: close() of the server cancels it
        tasks.add(task)
        task.add_done_callback(tasks.discard)


_EAGER = (
    _enter_task is not None and _leave_task is not None and _current_tasks is not None
)


class OpRunner:
    """Runs a server's puts and calls on its loop (see the module doc): the
    first step of each at once, as a step of a standing Task; one that
    waits goes on in that Task, which is then in ``tasks`` until it ends
    (``close`` cancels them all)."""

    def __init__(self) -> None:
        self.tasks: set[asyncio.Task[Any]] = set()
        self._task: asyncio.Task[Any] | None = None  # the standing Task
        self._slot: _Slot | None = None
        self._context: contextvars.Context | None = None
        self._vars: dict[Any, Any] = {}  # its context's variables when made
        self._nvars = 0  # how many

    def start(self, op: Any, coro: Coroutine[Any, Any, None]) -> None:
        """Run ``coro``, which answers ``op`` (an Exception it raises is
        ``op``'s error), on the running loop; called from a loop callback
        (as p4p's hand-over calls the handlers) its first step is taken now.
        """
        loop = asyncio.get_running_loop()
        # asyncio.current_task(loop), in line
        if not _EAGER or _current_tasks.get(loop) is not None:  # type: ignore[union-attr]
            start_op(op, coro, self.tasks)  # in a task: a Task of its own
            return
        task = self._task
        if task is None or task.done() or task.cancelling():
            task = self._stand(loop)
        context: contextvars.Context = self._context  # type: ignore[assignment]
        _enter_task(loop, task)  # type: ignore[misc]
        # its first step: _ENDED if it returned or raised an Exception (op's
        # error), else what _EagerStep keeps of it (the future it waits on,
        # or a BaseException it raised)
        try:
            first = ("yield", context.run(coro.send, None))
        except StopIteration:
            first = _ENDED
        except Exception as e:  # the client's error; the operation ends
            op.done(error=error_text(e))
            first = _ENDED
        except BaseException as e:
            first = ("raise", e)
        finally:
            _leave_task(loop, task)  # type: ignore[misc]
        if first is _ENDED:  # it returned (its error, if any, went to op)
            if len(context) != self._nvars or (
                self._nvars and any(context[k] is not v for k, v in self._vars.items())
            ):  # a variable left changed: the next operation gets a new Task
                self._task = None
                task.cancel()
            return
        # it waits (or raised a BaseException): the standing Task is its own
        slot = self._slot
        assert slot is not None
        self._task = None
        step = _EagerStep(op, coro)
        step._first = first
        slot.take(step)
        self.tasks.add(task)
        task.add_done_callback(self.tasks.discard)

    def _stand(self, loop: asyncio.AbstractEventLoop) -> asyncio.Task[Any]:
        """A new standing Task, waiting for an operation to hand over."""
        self._slot = slot = _Slot(loop)
        self._context = context = contextvars.copy_context()
        self._vars = dict(context)
        self._nvars = len(self._vars)
        self._task = task = loop.create_task(slot, context=context)  # type: ignore[arg-type]
        return task

    def close(self) -> None:
        """Cancel the standing Task and every operation still waiting."""
        if self._task is not None:
            self._task.cancel()
            self._task = None
        for task in list(self.tasks):
            task.cancel()


_ENDED = object()


class _Slot:
    """The coroutine of a standing Task: until an operation is handed over
    it waits on a future of its own; then it is that operation's
    :class:`_EagerStep` (the Task's next send gives back what the step
    took in the operation's first step gave). (The coroutine protocol, so
    that ``asyncio.Task`` takes it.)"""

    __slots__ = ("loop", "step", "idle")

    def __init__(self, loop: asyncio.AbstractEventLoop) -> None:
        self.loop = loop
        self.step: _EagerStep | None = None
        self.idle: asyncio.Future[None] | None = None

    def take(self, step: _EagerStep) -> None:
        """Hand ``step`` over: the Task goes on with it at its next turn."""
        self.step = step
        idle, self.idle = self.idle, None
        if idle is not None and not idle.done():
            idle.set_result(None)  # wakes the Task: its send goes to the step

    def send(self, value: Any) -> Any:
        step = self.step
        if step is not None:
            return step.send(value)
        idle = self.idle
        if idle is None or idle.done():
            idle = self.idle = self.loop.create_future()
        idle._asyncio_future_blocking = True  # what a Future's __await__ yields
        return idle

    def throw(self, *exc: Any) -> Any:
        if self.step is not None:
            return self.step.throw(*exc)
        self.idle = None
        if len(exc) == 1:
            raise exc[0]
        raise exc[1] if exc[1] is not None else exc[0]()

    def close(self) -> None:
        if self.step is not None:
            self.step.close()

    def __next__(self) -> Any:
        return self.send(None)

    def __iter__(self) -> _Slot:
        return self

    def __await__(self) -> Generator[Any, None, Any]:
        return self  # type: ignore[return-value]


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

"""The phase runner: every part function registered for a phase runs concurrently.

The phase ends when all have returned. The first exception cancels the
siblings and is raised as PhaseError naming the part and the phase; a
timeout cancels all of them and raises PhaseTimeoutError naming the parts
still running.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextvars
import inspect
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from malcolm.core import AbortedError, MalcolmError, PhaseTimeoutError

from .blocking import BlockingTask
from .signature import hook_nargs, hook_problem
from .task import Task


@dataclass(frozen=True)
class Hook:
    """One part function registered for one phase."""

    part: str
    phase: str
    func: Callable[..., Any]
    is_async: bool
    nargs: int  # how many of (task, device) it takes

    @classmethod
    def make(cls, part: str, phase: str, func: Callable[..., Any]) -> Hook:
        """The hook for ``func``; TypeError if it cannot take ``(task, device)``."""
        problem = hook_problem(func)
        if problem is not None:
            raise TypeError(f"part {part!r}, phase {phase}: {problem}")
        nargs = hook_nargs(func)
        return cls(part, phase, func, inspect.iscoroutinefunction(func), nargs)


class PhaseError(MalcolmError):
    """A part function raised during a phase."""

    def __init__(self, phase: str, part: str, cause: BaseException) -> None:
        self.phase = phase
        self.part = part
        self.cause = cause
        text = str(cause) or type(cause).__name__
        if not isinstance(cause, MalcolmError):
            text = f"{type(cause).__name__}: {text}"
        super().__init__(f"{phase} phase: part {part!r} failed: {text}")


#: how long cancelled async hooks get to finish their clean-up
CANCEL_GRACE = 1.0

_executor: concurrent.futures.ThreadPoolExecutor | None = None


def executor() -> concurrent.futures.ThreadPoolExecutor:
    """The worker threads plain ``def`` hook functions run in."""
    global _executor
    if _executor is None:
        _executor = concurrent.futures.ThreadPoolExecutor(
            max_workers=64, thread_name_prefix="malcolm-hook"
        )
    return _executor


def _retrieve(fut: asyncio.Future[Any]) -> None:
    if not fut.cancelled():
        fut.exception()


async def _run_alone(
    phase: str,
    hook: Hook,
    tasks: Mapping[str, Task],
    device: Any,
    timeout: float | None,
) -> dict[str, Any]:
    """One async hook: awaited in the caller's task (no sibling to run
    beside it), with the same outcomes as the general case.

    The timeout is kept as ``asyncio.timeout`` keeps it (a timer that
    cancels this task; its cancellation is taken back when it fired), with
    one timer handle and no context manager per phase."""
    args = (tasks[hook.part], device)[: hook.nargs]
    me = asyncio.current_task()
    assert me is not None
    expired = False
    handle: asyncio.TimerHandle | None = None
    if timeout is not None:
        cancelling = me.cancelling()

        def expire() -> None:
            nonlocal expired
            expired = True
            me.cancel()

        handle = asyncio.get_running_loop().call_later(timeout, expire)
    try:
        result = await hook.func(*args)
    except asyncio.CancelledError:
        if expired and me.uncancel() <= cancelling:
            raise PhaseTimeoutError(
                f"{phase} phase timed out after {timeout} s waiting for"
                f" part(s) {hook.part}"
            ) from None
        if me.cancelling():
            raise  # the phase itself was cancelled (abort, pause, disable)
        # cancelled from inside (a stopped task's future)
        raise PhaseError(
            phase, hook.part, AbortedError(f"{hook.part} was cancelled")
        ) from None
    except Exception as e:
        if expired:
            me.uncancel()
        raise PhaseError(phase, hook.part, e) from e
    finally:
        if handle is not None:
            handle.cancel()
    if expired:  # it finished although the timer fired: not a timeout
        me.uncancel()
    return {hook.part: result}


async def run_phase(
    phase: str,
    hooks: Sequence[Hook],
    tasks: Mapping[str, Task],
    device: Any,
    timeout: float | None = None,
) -> dict[str, Any]:
    """Run ``hooks`` concurrently; return ``{part: returned value}``."""
    if not hooks:
        return {}
    if len(hooks) == 1 and hooks[0].is_async:
        return await _run_alone(phase, hooks[0], tasks, device, timeout)
    loop = asyncio.get_running_loop()
    running: dict[asyncio.Future[Any], Hook] = {}
    blocking: list[BlockingTask] = []
    for hook in hooks:
        task = tasks[hook.part]
        if hook.is_async:
            args = (task, device)[: hook.nargs]
            fut = asyncio.ensure_future(hook.func(*args))
        else:
            btask = BlockingTask(task)
            blocking.append(btask)
            args = (btask, device)[: hook.nargs]
            # the thread runs in a copy of this context (as a task would), so
            # what it starts on the loop carries the same context variables
            context = contextvars.copy_context()
            fut = loop.run_in_executor(
                executor(), context.run, btask.call, hook.func, *args
            )
        running[fut] = hook

    def cancel_all() -> None:
        for fut in running:
            fut.cancel()
            # what a cancelled hook raises while it stops is not the phase's
            # error; retrieved so that asyncio does not report it as lost
            fut.add_done_callback(_retrieve)
        for btask in blocking:
            btask.cancel()

    async def cancel_and_settle() -> None:
        """Cancel all; give async hooks a moment to run their clean-up, so it
        happens before the block goes to Fault (threads cannot be waited for:
        their blocked Task calls raise AbortedError)."""
        cancel_all()
        waiting = [f for f, h in running.items() if h.is_async and not f.done()]
        if waiting:
            await asyncio.wait(waiting, timeout=CANCEL_GRACE)

    try:
        done, pending = await asyncio.wait(
            running, timeout=timeout, return_when=asyncio.FIRST_EXCEPTION
        )
    except asyncio.CancelledError:
        cancel_all()
        raise
    for fut in done:
        if not fut.cancelled() and fut.exception() is not None:
            await cancel_and_settle()
            raise PhaseError(phase, running[fut].part, fut.exception()) from (
                fut.exception()
            )
    if pending:
        await cancel_and_settle()
        parts = ", ".join(sorted({running[f].part for f in pending}))
        raise PhaseTimeoutError(
            f"{phase} phase timed out after {timeout} s waiting for part(s) {parts}"
        )
    for fut in done:
        if fut.cancelled():  # cancelled by someone else (a stopped task)
            await cancel_and_settle()
            part = running[fut].part
            raise PhaseError(phase, part, AbortedError(f"{part} was cancelled"))
    return {running[f].part: f.result() for f in done}

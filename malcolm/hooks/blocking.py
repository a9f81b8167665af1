"""The Task API for plain ``def`` hook functions, which run in a worker thread.

:class:`BlockingTask` gives the calls of :class:`~malcolm.hooks.task.Task`,
blocking: each hands its work to the process's loop and waits for it.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import threading
import weakref
from collections.abc import Callable, Mapping
from typing import Any

from malcolm.core import AbortedError
from malcolm.core.errors import still_running
from malcolm.core.threads import call_threadsafe, marshalling

from .task import Task, flatten

_current = threading.local()


def current_blocking_task() -> BlockingTask | None:
    """The BlockingTask of the hook function running in this thread, if any."""
    return getattr(_current, "task", None)


class BlockingTask:
    """The Task API for plain ``def`` hook functions running in a worker thread.

    Every call hands work to the process's loop and blocks until it is done.
    ``put_async`` and ``when_matches`` return ``concurrent.futures.Future``.
    When the phase is cancelled (abort, pause, a sibling's error), blocked
    calls raise AbortedError.
    """

    def __init__(self, task: Task) -> None:
        self._task = task
        self.part = task.part
        self.process = task.process
        self.cancelled = False
        self._inflight: set[concurrent.futures.Future[Any]] = set()
        self._waits: weakref.WeakSet[concurrent.futures.Future[Any]] = weakref.WeakSet()
        self._callbacks = concurrent.futures.ThreadPoolExecutor(
            max_workers=1, thread_name_prefix=f"{task.part}-callbacks"
        )

    def call(self, func: Callable[..., Any], *args: Any) -> Any:
        """Run ``func`` in this thread as part of this task (views use it).

        Changes ``func`` makes to block state (``attr.set_value(...)``) are
        run on the process's loop while this thread waits for them.
        """
        previous = current_blocking_task()
        _current.task = self
        loop = self.process.loop
        assert loop is not None
        try:
            with marshalling(loop, self._run_on_loop):
                return func(*args)
        finally:
            _current.task = previous

    def _run_on_loop(self, func: Callable[..., Any], *args: Any) -> Any:
        return self._wait(self._submit(lambda: func(*args)))

    def _submit(self, coro_fn: Callable[[], Any]) -> concurrent.futures.Future[Any]:
        """Run ``coro_fn()`` on the loop (awaiting what it returns)."""
        if self.cancelled:
            raise AbortedError(f"{self.part}: the phase was cancelled")
        loop = self.process.loop
        assert loop is not None
        fut = call_threadsafe(loop, coro_fn)
        self._inflight.add(fut)
        fut.add_done_callback(self._inflight.discard)
        return fut

    def _wait(self, fut: concurrent.futures.Future[Any]) -> Any:
        try:
            return fut.result()
        except concurrent.futures.CancelledError:
            raise AbortedError(f"{self.part}: the phase was cancelled") from None

    def cancel(self) -> None:
        """Make blocked and later calls raise AbortedError."""
        self.cancelled = True
        for fut in list(self._inflight):
            fut.cancel()

    # ---- the API
    def put(self, target: Any, value: Any = None, timeout: float | None = None):
        self._wait(self._submit(lambda: self._task.put(target, value, timeout)))

    def put_async(self, target: Any, value: Any = None) -> Any:
        if isinstance(target, Mapping):
            return [self.put_async(t, v) for t, v in target.items()]
        return self._submit(lambda: self._task.put(target, value))

    def wait_all(self, *futures: Any, timeout: float | None = None) -> list[Any]:
        """Block until all are done; the timeout rule is the async Task's."""
        flat = flatten(futures)
        done, pending = concurrent.futures.wait(
            flat, timeout=timeout, return_when=concurrent.futures.FIRST_EXCEPTION
        )
        for f in flat:  # the first error, in the order they were given
            if f.done() and not f.cancelled() and f.exception() is not None:
                raise f.exception()  # type: ignore[misc]
        if pending:
            for f in pending:  # waits change nothing: drop them; puts go on
                if f in self._waits:
                    f.cancel()
            raise still_running(
                f"{self.part}: {len(pending)} of {len(flat)} operation(s)", timeout
            )
        return [self._wait(f) for f in flat]

    def when_matches(
        self, target: Any, value: Any, timeout: float | None = None
    ) -> concurrent.futures.Future[Any]:
        fut = self._submit(lambda: self._task.when_matches(target, value, timeout))
        self._waits.add(fut)
        return fut

    def subscribe(self, target: Any, callback: Callable[..., Any], *args: Any) -> int:
        def in_thread(v: Any, *a: Any) -> None:
            self._callbacks.submit(self.call, callback, v, *a)

        return self._wait(
            self._submit(lambda: self._task.subscribe(target, in_thread, *args))
        )

    def unsubscribe(self, sid: int) -> None:
        self._wait(self._submit(lambda: self._task.unsubscribe(sid)))

    def sleep(self, seconds: float) -> None:
        self._wait(self._submit(lambda: asyncio.sleep(seconds)))

    def report_progress(self, steps: int) -> None:
        self._wait(self._submit(lambda: self._task.report_progress(steps)))

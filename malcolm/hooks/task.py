"""The Task API parts use inside hook functions.

``Task`` is for ``async def`` hook functions (run on the process's loop);
``BlockingTask`` gives the same calls, blocking, to plain ``def`` hook
functions, which run in a worker thread.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import itertools
import threading
from collections.abc import Callable, Iterable, Mapping
from typing import TYPE_CHECKING, Any

from malcolm.core import AbortedError, Attribute, Subscription, WaitTimeoutError
from malcolm.core.threads import marshalling

from .views import FieldView

if TYPE_CHECKING:
    from malcolm.core import Process

Target = FieldView | Attribute | tuple[str, str]


def target_path(target: Any) -> list[str]:
    """The ``[mri, field]`` path a put/subscribe target names."""
    if isinstance(target, FieldView):
        return [target.mri, target.name]
    if isinstance(target, Attribute) and target.block is not None:
        return [target.block.mri, target.name]
    if isinstance(target, tuple | list) and len(target) == 2:
        return [str(target[0]), str(target[1])]
    raise TypeError(f"cannot put to or watch {target!r}: expected a block's field")


def _flatten(futures: Iterable[Any]) -> list[Any]:
    out: list[Any] = []
    for f in futures:
        if f is None:
            continue
        if isinstance(f, Mapping):
            out.extend(_flatten(f.values()))
        elif isinstance(f, list | tuple | set):
            out.extend(_flatten(f))
        else:
            out.append(f)
    return out


class Task:
    """Acts on blocks for one part: puts, waits, subscriptions, progress.

    Subscriptions and futures made through a task live until ``stop()``,
    which the controller calls on abort, disable and reset.
    """

    def __init__(
        self,
        process: Process,
        part: str,
        on_progress: Callable[[str, int], None] | None = None,
    ) -> None:
        self.process = process
        self.part = part
        self._on_progress = on_progress
        self._futures: set[asyncio.Future[Any]] = set()
        self._subs: dict[int, Subscription] = {}
        self._ids = itertools.count(1)

    # ---- puts
    async def put(
        self, target: Any, value: Any = None, timeout: float | None = None
    ) -> None:
        """Put and wait for completion; a dict puts many at once."""
        futures = self.put_async(target, value)
        await self.wait_all(futures, timeout=timeout)

    def put_async(self, target: Any, value: Any = None) -> Any:
        """Start put(s); returns a future, or a list of them for a dict."""
        if isinstance(target, Mapping):
            return [self.put_async(t, v) for t, v in target.items()]
        path = target_path(target)
        return self._track(asyncio.ensure_future(self.process.put(path, value)))

    def _track(self, fut: asyncio.Future[Any]) -> asyncio.Future[Any]:
        self._futures.add(fut)
        fut.add_done_callback(self._futures.discard)
        return fut

    async def wait_all(self, *futures: Any, timeout: float | None = None) -> list[Any]:
        """Wait for futures (or lists/dicts of them); the first error is raised."""
        flat = _flatten(futures)
        if not flat:
            return []
        try:
            return list(await asyncio.wait_for(asyncio.gather(*flat), timeout=timeout))
        except TimeoutError:
            raise WaitTimeoutError(
                f"{self.part}: {len(flat)} operation(s) not done after {timeout} s"
            ) from None

    # ---- waiting for values
    def when_matches(
        self, target: Any, value: Any, timeout: float | None = None
    ) -> asyncio.Future[Any]:
        """A future done when the field equals value (or value(field) is true)."""
        path = target_path(target)
        loop = asyncio.get_running_loop()
        fut: asyncio.Future[Any] = loop.create_future()
        match = value if callable(value) else (lambda v: v == value)
        last: list[Any] = [None]

        def on_value(v: Any) -> None:
            last[0] = v
            if not fut.done() and match(v):
                fut.set_result(v)

        sub = self.process.subscribe([*path, "value"], on_value, delta=False)

        async def waiter() -> Any:
            try:
                return await asyncio.wait_for(asyncio.shield(fut), timeout)
            except TimeoutError:
                want = getattr(value, "__name__", repr(value))
                raise WaitTimeoutError(
                    f"{'.'.join(path)} did not match {want} within {timeout} s"
                    f" (last value {last[0]!r})"
                ) from None
            finally:
                self.process.unsubscribe(sub)
                if not fut.done():
                    fut.cancel()

        return self._track(asyncio.ensure_future(waiter()))

    # ---- subscriptions
    def subscribe(self, target: Any, callback: Callable[..., Any], *args: Any) -> int:
        """Call ``callback(value, *args)`` now and on every change; returns an id."""
        path = target_path(target)

        def on_value(v: Any) -> None:
            result = callback(v, *args)
            if asyncio.iscoroutine(result):
                self._track(asyncio.ensure_future(result))

        sid = next(self._ids)
        self._subs[sid] = self.process.subscribe([*path, "value"], on_value, False)
        return sid

    def unsubscribe(self, sid: int) -> None:
        sub = self._subs.pop(sid, None)
        if sub is not None:
            self.process.unsubscribe(sub)

    # ---- misc
    async def sleep(self, seconds: float) -> None:
        await asyncio.sleep(seconds)

    def report_progress(self, steps: int) -> None:
        """Tell the controller how many steps of the scan this part has done."""
        if self._on_progress is not None:
            self._on_progress(self.part, int(steps))

    def stop(self) -> None:
        """Cancel outstanding futures and drop all subscriptions."""
        for fut in list(self._futures):
            fut.cancel()
        for sid in list(self._subs):
            self.unsubscribe(sid)


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
        if self.cancelled:
            raise AbortedError(f"{self.part}: the phase was cancelled")
        loop = self.process.loop
        assert loop is not None

        async def runner() -> Any:
            result = coro_fn()
            if asyncio.isfuture(result) or asyncio.iscoroutine(result):
                return await result
            return result

        fut = asyncio.run_coroutine_threadsafe(runner(), loop)
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
        flat = _flatten(futures)
        done, pending = concurrent.futures.wait(flat, timeout=timeout)
        if pending:
            for fut in pending:  # as the async Task does: nothing left behind
                fut.cancel()
            raise WaitTimeoutError(
                f"{self.part}: {len(pending)} operation(s) not done after {timeout} s"
            )
        return [self._wait(f) for f in flat]

    def when_matches(
        self, target: Any, value: Any, timeout: float | None = None
    ) -> concurrent.futures.Future[Any]:
        return self._submit(lambda: self._task.when_matches(target, value, timeout))

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

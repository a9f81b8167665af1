"""ThreadedProcess: a Process on an asyncio loop in a background thread,
driven by blocking calls from any other thread."""

from __future__ import annotations

import asyncio
import concurrent.futures
import logging
import queue
import threading
from collections.abc import Callable, Coroutine, Iterable, Sequence
from typing import Any, TypeVar

from malcolm.core import (
    AbortedError,
    BadValueError,
    Process,
    Subscription,
    WaitTimeoutError,
)
from malcolm.core.errors import still_running

from .files import from_file
from .loop import new_event_loop
from .proxies import BlockProxy

# the logger of the single-module malcolm.embed, kept so records' names do not
# change
log = logging.getLogger("malcolm.embed")

T = TypeVar("T")

_STOP = object()

#: Seconds that calls still running when a ThreadedProcess stops get to finish.
SHUTDOWN_GRACE = 1.0


def start_process(process: Process, timeout: float | None = None) -> ThreadedProcess:
    """Start ``process`` on a loop in a background thread; blocks until ready."""
    tp = ThreadedProcess(process)
    tp.start(timeout)
    return tp


class EmbeddedSubscription:
    """A subscription made through a ThreadedProcess; ``unsubscribe()`` ends it."""

    def __init__(self, owner: ThreadedProcess, path: Sequence[str], callback: Any):
        self.owner = owner
        self.path = list(path)
        self.callback = callback
        self.active = True
        self._sub: Subscription | None = None

    def unsubscribe(self) -> None:
        """Stop delivery, including changes made but not yet delivered."""
        if not self.active:
            return
        self.active = False
        self.owner._unsubscribe(self)

    def __enter__(self) -> EmbeddedSubscription:
        return self

    def __exit__(self, *exc: object) -> None:
        self.unsubscribe()

    def __repr__(self) -> str:
        return f"<EmbeddedSubscription {'.'.join(self.path)} active={self.active}>"


class ThreadedProcess:
    """A Process run on an asyncio loop in a background thread.

    Every method blocks the calling thread until the loop has done the work
    and may be called from any thread except the loop's own (which would
    wait for itself: that raises RuntimeError). ``timeout`` arguments are in
    seconds; ``None`` waits for ever. A timeout stops the caller waiting and
    raises WaitTimeoutError; the call or put goes on (call abort() to stop
    it).
    """

    def __init__(self, process: Process) -> None:
        self.process = process
        self.loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._dispatcher: threading.Thread | None = None
        self._queue: queue.SimpleQueue[Any] = queue.SimpleQueue()
        self._subs: list[EmbeddedSubscription] = []
        self._lock = threading.Lock()
        self.started = False

    @classmethod
    def from_file(cls, path: str, search_path: Iterable[str] = ()) -> ThreadedProcess:
        """A (not started) ThreadedProcess for the blocks of a process file."""
        return cls(from_file(path, search_path))

    # ---- lifecycle
    def start(self, timeout: float | None = None) -> ThreadedProcess:
        """Start the loop thread and run ``process.start()`` on it."""
        with self._lock:
            if self._thread is not None:
                raise RuntimeError(f"process {self.process.name!r} already started")
            ready = threading.Event()
            self._thread = threading.Thread(
                target=self._run_loop,
                args=(ready,),
                name=f"malcolm-{self.process.name}-loop",
                daemon=True,
            )
            self._thread.start()
            ready.wait()
            self._dispatcher = threading.Thread(
                target=self._dispatch,
                name=f"malcolm-{self.process.name}-callbacks",
                daemon=True,
            )
            self._dispatcher.start()
        try:
            self._run(self.process.start(), timeout, "start")
        except WaitTimeoutError:
            self._shutdown()  # the loop and its thread go: start does not go on
            raise WaitTimeoutError(
                f"{self.process.name}: start did not finish within {timeout} s;"
                " the process was stopped"
            ) from None
        except BaseException:
            self._shutdown()
            raise
        self.started = True
        return self

    def stop(self, timeout: float | None = None) -> None:
        """Stop the process, then the loop and its thread. Safe to call twice."""
        if self._thread is None:
            return
        self._check_thread()
        try:
            if self.started:
                self._run(self.process.stop(), timeout, "stop")
        except WaitTimeoutError:
            raise WaitTimeoutError(
                f"{self.process.name}: stop did not finish within {timeout} s;"
                " the loop was stopped anyway"
            ) from None
        finally:
            self.started = False
            for sub in list(self._subs):
                sub.active = False
            self._subs.clear()
            self._shutdown()

    def __enter__(self) -> ThreadedProcess:
        if self._thread is None:
            self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _run_loop(self, ready: threading.Event) -> None:
        loop = new_event_loop()
        asyncio.set_event_loop(loop)
        self.loop = loop
        loop.call_soon(ready.set)  # once the loop is running
        try:
            loop.run_forever()
            # let calls that process.stop() interrupted finish (with their
            # AbortedError) before cancelling whatever is left
            tasks = [t for t in asyncio.all_tasks(loop) if not t.done()]
            if tasks:
                loop.run_until_complete(asyncio.wait(tasks, timeout=SHUTDOWN_GRACE))
            tasks = [t for t in asyncio.all_tasks(loop) if not t.done()]
            for t in tasks:
                t.cancel()
            if tasks:
                loop.run_until_complete(asyncio.gather(*tasks, return_exceptions=True))
            loop.run_until_complete(loop.shutdown_asyncgens())
        finally:
            loop.close()

    def _shutdown(self) -> None:
        loop, thread = self.loop, self._thread
        if loop is not None and not loop.is_closed():
            loop.call_soon_threadsafe(loop.stop)
        if thread is not None and thread is not threading.current_thread():
            thread.join()
        dispatcher = self._dispatcher
        if dispatcher is not None:
            self._queue.put(_STOP)
            if dispatcher is not threading.current_thread():
                dispatcher.join()
        self._thread = self._dispatcher = None
        self.loop = None

    def _dispatch(self) -> None:
        while True:
            item = self._queue.get()
            if item is _STOP:
                return
            sub, payload = item
            if not sub.active:
                continue
            try:
                sub.callback(payload)
            except Exception:
                log.exception("subscriber %r raised", sub)

    # ---- running work on the loop
    def _check_thread(self) -> None:
        if self._thread is not None and threading.current_thread() is self._thread:
            raise RuntimeError(
                "a blocking ThreadedProcess call was made on the process's own loop;"
                " use the Process's async methods there"
            )

    def _loop(self) -> asyncio.AbstractEventLoop:
        loop = self.loop
        if loop is None or not loop.is_running():
            raise RuntimeError(f"process {self.process.name!r} is not running")
        return loop

    def _run(self, coro: Coroutine[Any, Any, T], timeout: float | None, what: str) -> T:
        """Run ``coro`` on the loop and wait for it.

        After ``timeout`` seconds raises WaitTimeoutError: the work goes on
        (a timeout never cancels a call or put; docs/embedding.md).
        """
        try:
            self._check_thread()
            future = asyncio.run_coroutine_threadsafe(coro, self._loop())
        except BaseException:
            coro.close()
            raise
        try:
            return future.result(timeout)
        except concurrent.futures.CancelledError:
            raise AbortedError(
                f"{self.process.name}: {what} was cancelled (the process stopped)"
            ) from None
        except concurrent.futures.TimeoutError:
            if not future.done():
                future.add_done_callback(self._report_late(what))
                raise still_running(f"{self.process.name}: {what}", timeout) from None
            raise  # the work itself raised a TimeoutError

    @staticmethod
    def _report_late(what: str) -> Callable[[concurrent.futures.Future[Any]], None]:
        def report(future: concurrent.futures.Future[Any]) -> None:
            if not future.cancelled() and future.exception() is not None:
                log.warning(
                    "%s, which outlived its timeout, failed: %s",
                    what,
                    future.exception(),
                )

        return report

    def _run_future(self, coro: Coroutine[Any, Any, T]) -> concurrent.futures.Future[T]:
        try:
            return asyncio.run_coroutine_threadsafe(coro, self._loop())
        except BaseException:
            coro.close()
            raise

    def call_in_loop(
        self, func: Callable[..., T], *args: Any, timeout: float | None = None
    ) -> T:
        """Run plain ``func(*args)`` on the loop thread; return its result."""

        async def run() -> T:
            return func(*args)

        return self._run(run(), timeout, getattr(func, "__name__", "call"))

    # ---- the Process API, blocking
    def get(self, path: Sequence[str], timeout: float | None = None) -> Any:
        """The plain data at ``path``, e.g. ``["COUNTER", "counter", "value"]``."""
        return self.call_in_loop(self.process.get, list(path), timeout=timeout)

    def put(self, path: Sequence[str], value: Any, timeout: float | None = None):
        """Put to ``[mri, attribute]``; returns once the put is complete."""
        self._run(self.process.put(list(path), value), timeout, f"put {path}")

    def post(
        self,
        path: Sequence[str],
        params: dict[str, Any] | None = None,
        timeout: float | None = None,
    ) -> Any:
        """Call the method at ``[mri, method]``; return what it returns."""
        return self._run(self.process.post(list(path), params), timeout, f"{path}")

    def post_async(
        self, path: Sequence[str], params: dict[str, Any] | None = None
    ) -> concurrent.futures.Future[Any]:
        """Start a call and return at once; ``.result()`` waits for it."""
        return self._run_future(self.process.post(list(path), params))

    def subscribe(
        self, path: Sequence[str], callback: Callable[[Any], None], delta: bool = True
    ) -> EmbeddedSubscription:
        """Like Process.subscribe, but ``callback`` runs in the dispatch thread.

        The first call carries the current value. Returns a handle whose
        ``unsubscribe()`` stops delivery.
        """
        handle = EmbeddedSubscription(self, path, callback)

        def on_loop() -> None:
            handle._sub = self.process.subscribe(
                list(path), lambda payload: self._queue.put((handle, payload)), delta
            )

        self.call_in_loop(on_loop)
        self._subs.append(handle)
        return handle

    def _unsubscribe(self, handle: EmbeddedSubscription) -> None:
        if handle in self._subs:
            self._subs.remove(handle)
        sub = handle._sub
        if sub is not None and self.loop is not None and self.loop.is_running():
            if threading.current_thread() is self._thread:
                self.process.unsubscribe(sub)
            else:
                self.call_in_loop(self.process.unsubscribe, sub)

    def when(
        self,
        path: Sequence[str],
        match: Any,
        timeout: float | None = None,
        bad_values: Iterable[Any] = (),
    ) -> Any:
        """Wait until the value at ``path`` equals ``match`` (or, if ``match``
        is callable, ``match(value)`` is true); return that value.

        Raises WaitTimeoutError after ``timeout`` seconds, and BadValueError
        as soon as the value is one of ``bad_values``.
        """
        path = list(path)
        bad = list(bad_values)
        test = match if callable(match) else (lambda v: v == match)
        name = ".".join(path)

        async def wait() -> Any:
            loop = asyncio.get_running_loop()
            found: asyncio.Future[Any] = loop.create_future()
            last: list[Any] = [None]

            def check(value: Any) -> None:
                last[0] = value
                if found.done():
                    return
                if value in bad:
                    found.set_exception(
                        BadValueError(
                            f"{name} is {value!r} while waiting for {match!r}"
                        )
                    )
                elif test(value):
                    found.set_result(value)

            sub = self.process.subscribe(path, check, delta=False)
            try:
                return await asyncio.wait_for(found, timeout)
            except TimeoutError:
                raise WaitTimeoutError(
                    f"{name} was not {match!r} after {timeout}s (it is {last[0]!r})"
                ) from None
            finally:
                self.process.unsubscribe(sub)

        return self._run(wait(), None, f"when {name}")

    # ---- blocks
    @property
    def mris(self) -> list[str]:
        return self.call_in_loop(lambda: self.process.mris)

    def block(self, mri: str) -> BlockProxy:
        """A proxy for block ``mri``; NotFoundError if there is none."""
        self.call_in_loop(self.process.get_block, mri)
        return BlockProxy(self, mri)

    def __repr__(self) -> str:
        state = "running" if self.started else "stopped"
        return f"<ThreadedProcess {self.process.name!r} {state}>"

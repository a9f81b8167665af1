"""The Task API parts use inside hook functions.

``Task`` is for ``async def`` hook functions (run on the process's loop);
:class:`~malcolm.hooks.blocking.BlockingTask` gives the same calls,
blocking, to plain ``def`` hook functions, which run in a worker thread.
"""

from __future__ import annotations

import asyncio
import inspect
import itertools
import logging
import weakref
from collections.abc import Callable, Iterable, Mapping
from typing import TYPE_CHECKING, Any

from malcolm.core import (
    Attribute,
    BadValueError,
    Subscription,
    WaitTimeoutError,
)
from malcolm.core.errors import still_running

from .origin import WRITER, on_behalf_of
from .views import FieldView

if TYPE_CHECKING:
    from malcolm.core import Process

log = logging.getLogger(__name__)

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


def flatten(futures: Iterable[Any]) -> list[Any]:
    """The futures in ``futures`` and in the lists, tuples, sets and dict
    values among them, in order; Nones left out."""
    out: list[Any] = []
    for f in futures:
        if f is None:
            continue
        if isinstance(f, Mapping):
            out.extend(flatten(f.values()))
        elif isinstance(f, list | tuple | set):
            out.extend(flatten(f))
        else:
            out.append(f)
    return out


class Task:
    """Acts on blocks for one part: puts, waits, subscriptions, progress.

    Subscriptions and futures made through a task live until ``stop()``,
    which the controller calls on abort, disable and reset.

    With an ``origin`` (its controller's mri), every put the task makes, and
    everything its subscription callbacks do (an awaitable they return
    included), is made on that block's behalf (:mod:`.origin`), whichever
    thread or notification started it.

    Timeouts follow one rule (docs/embedding.md): a timeout stops the caller
    waiting and raises WaitTimeoutError saying the operation goes on; it
    never cancels a put or a call. ``when_matches`` waits change nothing, so
    a wait that gives up drops them.
    """

    def __init__(
        self,
        process: Process,
        part: str,
        on_progress: Callable[[str, int], None] | None = None,
        origin: str | None = None,
    ) -> None:
        self.process = process
        self.part = part
        #: the mri on whose behalf this task writes (None: whoever calls it)
        self.origin = origin
        self._on_progress = on_progress
        self._futures: set[asyncio.Future[Any]] = set()
        #: the when_matches futures among them (dropped by a wait that gives
        #: up); made by the first when_matches: a process has a Task per part
        self._waits: weakref.WeakSet[asyncio.Future[Any]] | None = None
        self._subs: dict[int, Subscription] = {}
        self._ids = itertools.count(1)

    # ---- puts
    async def put(
        self, target: Any, value: Any = None, timeout: float | None = None
    ) -> None:
        """Put and wait for completion; a dict puts many at once.

        After ``timeout`` seconds raises WaitTimeoutError; the put goes on.
        """
        if timeout is None and not isinstance(target, Mapping):
            # one put and no timeout: awaited in place, on the task's behalf
            # (no Task of its own and no wait for it; cancelling the caller
            # cancels it, as it cancels what a wait waits for)
            path = target_path(target)
            if self.origin is None:
                await self.process.put(path, value)
                return
            token = WRITER.set(self.origin)
            try:
                await self.process.put(path, value)
            finally:
                WRITER.reset(token)
            return
        futures = self.put_async(target, value)
        await self.wait_all(futures, timeout=timeout)

    def put_async(self, target: Any, value: Any = None) -> Any:
        """Start put(s); returns a future, or a list of them for a dict."""
        if isinstance(target, Mapping):
            return [self.put_async(t, v) for t, v in target.items()]
        path = target_path(target)
        with on_behalf_of(self.origin):  # the put's task copies the context
            return self._track(asyncio.ensure_future(self.process.put(path, value)))

    def _track(self, fut: asyncio.Future[Any]) -> asyncio.Future[Any]:
        self._futures.add(fut)
        fut.add_done_callback(self._done)
        return fut

    def _done(self, fut: asyncio.Future[Any]) -> None:
        self._futures.discard(fut)
        if not fut.cancelled() and fut.exception() is not None:
            # retrieved here, so that one nobody waits for is not reported as
            # "never retrieved"; whoever waits for it still gets it
            log.debug("%s: %r failed: %s", self.part, fut, fut.exception())

    async def wait_all(self, *futures: Any, timeout: float | None = None) -> list[Any]:
        """Wait for futures (or lists/dicts of them); the first error is raised.

        After ``timeout`` seconds raises WaitTimeoutError: puts and calls go
        on, ``when_matches`` waits among them are dropped. If the caller is
        cancelled (abort), what it waited for is cancelled too.
        """
        flat = flatten(futures)
        if not flat:
            return []
        flat = [
            f if asyncio.isfuture(f) else self._track(asyncio.ensure_future(f))
            for f in flat
        ]
        if len(flat) == 1 and timeout is None:
            # awaited as it is: its error raised, and cancelling the caller
            # cancels it (what the general case does, without asyncio.wait)
            return [await flat[0]]
        try:
            done, pending = await asyncio.wait(
                flat, timeout=timeout, return_when=asyncio.FIRST_EXCEPTION
            )
        except asyncio.CancelledError:
            for f in flat:
                f.cancel()
            raise
        for f in flat:  # the first error, in the order they were given
            if f.done() and not f.cancelled() and f.exception() is not None:
                raise f.exception()  # type: ignore[misc]
        if pending:
            self._give_up(pending)
            raise still_running(
                f"{self.part}: {len(pending)} of {len(flat)} operation(s)", timeout
            )
        return [f.result() for f in flat]

    def _give_up(self, pending: Iterable[asyncio.Future[Any]]) -> None:
        """Drop the waits among ``pending``; log what the others end with."""
        waits = self._waits if self._waits is not None else ()
        for f in pending:
            if f in waits:
                f.cancel()
            else:
                f.add_done_callback(self._report_late)

    def _report_late(self, fut: asyncio.Future[Any]) -> None:
        if not fut.cancelled() and fut.exception() is not None:
            log.warning(
                "%s: an operation that outlived its timeout failed: %s",
                self.part,
                fut.exception(),
            )

    # ---- waiting for values
    def when_matches(
        self, target: Any, value: Any, timeout: float | None = None
    ) -> asyncio.Future[Any]:
        """A future done when the field equals value (or value(field) is true).

        Values are compared as the attribute holds them (its meta's canonical
        form: arrays are tuples, tables dicts of tuples), so lists, tuples and
        table rows or columns all match; a predicate gets that form too. A
        ``value`` that does not fit the attribute raises BadValueError now.
        """
        path = target_path(target)
        attr = self.process.get_block(path[0]).attribute(path[1])
        if callable(value):
            match = value
        else:
            want = attr.validate(value)

            def match(v: Any) -> bool:
                return bool(v == want)

        loop = asyncio.get_running_loop()
        fut: asyncio.Future[Any] = loop.create_future()
        last: list[Any] = [None]

        def on_value(plain: Any) -> None:
            try:
                v = attr.meta.validate(plain)
            except BadValueError:
                v = plain  # e.g. the field was replaced by another kind
            last[0] = v
            if fut.done():
                return
            try:
                if match(v):
                    fut.set_result(v)
            except Exception as e:  # a predicate that raises ends the wait
                fut.set_exception(e)

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

        waiting = self._track(asyncio.ensure_future(waiter()))
        if self._waits is None:
            self._waits = weakref.WeakSet()
        self._waits.add(waiting)
        return waiting

    # ---- subscriptions
    def subscribe(self, target: Any, callback: Callable[..., Any], *args: Any) -> int:
        """Call ``callback(value, *args)`` now and on every change; returns an id.

        The callback (and an awaitable it returns, run as a future of this
        task) runs on behalf of the task's origin, not of whoever made the
        change it is told of."""
        path = target_path(target)

        def on_value(v: Any) -> None:
            with on_behalf_of(self.origin):
                result = callback(v, *args)
                if inspect.isawaitable(result):
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

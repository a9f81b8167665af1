"""The operation serialiser: one operation at a time, and what a failure does.

A mixin of :class:`~malcolm.controllers.base.Controller`. An operation is a
call that moves the block (configure, run, reset, load...). It runs as a
task of its own, so that abort, disable and faults can cancel it while its
caller waits. The failure rule:

- an operation that fails while the block rests (nothing moved yet, e.g. a
  part's Validate refuses a configure) is **refused**: the error goes to the
  caller and nothing changes;
- one that fails after the block left a resting state sends it to **Fault**
  (``health`` says why) and the caller gets the error;
- one cancelled by a fault gives its caller the fault's reason; one
  cancelled by abort or disable gives AbortedError.
"""

from __future__ import annotations

import asyncio
import logging
import weakref
from collections.abc import Coroutine
from typing import TYPE_CHECKING, Any

from malcolm.core import (
    AbortedError,
    BadValueError,
    MalcolmError,
    NotAllowedError,
)

log = logging.getLogger(__name__)


def _retrieve(fut: asyncio.Future[Any]) -> None:
    """Mark a finished future's outcome as seen (nobody waits for it any more)."""
    if not fut.cancelled() and fut.exception() is not None:
        log.debug("an operation nobody waited for ended: %s", fut.exception())


class Operations:
    """One operation at a time; interrupters (abort, disable) take over."""

    mri: str
    _op: asyncio.Future[Any] | None
    _op_name: str
    _claim: object | None  # an interrupter waiting to take over
    _claim_name: str
    _cancel_reasons: weakref.WeakKeyDictionary[asyncio.Future[Any], str]

    if TYPE_CHECKING:  # from the other parts of Controller
        current: str

        def is_busy(self) -> bool: ...
        async def go_fault(self, error: BaseException | str) -> None: ...

    def _init_operations(self) -> None:
        self._op = None
        self._op_name = ""
        self._claim = None
        self._claim_name = ""
        self._cancel_reasons = weakref.WeakKeyDictionary()

    def side_operations(self) -> list[asyncio.Future[Any]]:
        """Work running beside the main operation (a runnable's seek)."""
        return []

    def busy_with(self) -> str | None:
        """What is in progress (so another operation must wait), or None."""
        if self._claim is not None:
            return self._claim_name
        if self._op is not None and not self._op.done():
            return self._op_name
        if any(not f.done() for f in self.side_operations()):
            return "a pause or seek"
        return None

    def refuse_if_busy(self, name: str) -> None:
        """NotAllowedError if an operation is in progress."""
        busy = self.busy_with()
        if busy is not None:
            raise NotAllowedError(
                f"{self.mri}: cannot {name} while {busy} is in progress"
                f" (state {self.current})"
            )

    async def operation(
        self, name: str, coro: Coroutine[Any, Any, Any], interrupt: bool = False
    ) -> Any:
        """Run ``coro`` as the block's one operation (see the module's rules).

        ``interrupt`` operations (abort, disable) cancel whatever is in
        progress first; of two racing interrupters the later one wins and the
        earlier gets AbortedError. Others are refused while anything runs.
        """
        if not interrupt:
            try:
                self.refuse_if_busy(name)
            except NotAllowedError:
                coro.close()
                raise
        else:
            claim = object()
            self._claim, self._claim_name = claim, name
            try:
                await self.cancel_operation()
            finally:
                superseded = self._claim is not claim
                if not superseded:
                    self._claim = None
            if superseded:
                coro.close()
                raise AbortedError(
                    f"{self.mri}: {name} was superseded by {self._claim_name}"
                )
        op = asyncio.ensure_future(self._guarded(name, coro))
        self._op, self._op_name = op, name
        # wait for it without being it: the caller's cancellation must not
        # cancel the operation (asyncio.wait's way, with one future)
        ended = op.get_loop().create_future()

        def end(_: asyncio.Future[Any]) -> None:
            if not ended.done():
                ended.set_result(None)

        op.add_done_callback(end)
        try:
            await ended
        except asyncio.CancelledError:
            # the caller went away; the operation goes on: its outcome is
            # the block's state, and nobody is left to read its error
            op.remove_done_callback(end)
            op.add_done_callback(_retrieve)
            raise
        return self.outcome(op, name)

    def outcome(self, op: asyncio.Future[Any], name: str) -> Any:
        """The result of a finished operation ``name``; if it was cancelled,
        the fault's reason (MalcolmError) or AbortedError."""
        if op.cancelled():
            reason = self._cancel_reasons.pop(op, None)
            if reason is not None:
                raise MalcolmError(reason)
            raise AbortedError(f"{self.mri}: {name} was aborted")
        return op.result()

    async def cancel_operation(self) -> None:
        """Cancel the main operation and any side work, and wait for them."""
        running = [f for f in [self._op, *self.side_operations()] if f is not None]
        running = [f for f in running if not f.done()]
        for f in running:
            f.cancel()
        if running:
            await asyncio.wait(running)

    def cancel_now(self, reason: str | None = None) -> None:
        """Cancel everything in progress but the calling task, without waiting.

        With a ``reason`` (a fault's), the cancelled operation's caller gets
        it instead of AbortedError.
        """
        me = asyncio.current_task()
        for f in [self._op, *self.side_operations()]:
            if f is not None and not f.done() and f is not me:
                if reason is not None:
                    self._cancel_reasons[f] = reason
                f.cancel()

    async def _guarded(self, name: str, coro: Coroutine[Any, Any, Any]) -> Any:
        try:
            return await coro
        except asyncio.CancelledError:
            raise
        except Exception as e:
            if self.is_busy():
                # the block left a resting state: it must not stay busy
                if isinstance(e, NotAllowedError | BadValueError):
                    await self.go_fault(f"{name} stopped half way: {e}")
                else:
                    await self.go_fault(e)
            # else refused: nothing moved, nothing changed
            raise

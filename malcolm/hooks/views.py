"""Views of blocks that parts hold: ``self.child.xml`` names an attribute of a child.

A view does not own data: it names ``(mri, field)`` and reads through the
process. ``view.xml.put(v)`` works from a worker thread (plain ``def`` hook
functions) and is awaitable as ``await view.xml.put_async(v)`` on the loop;
``view.configure(...)`` (or ``.call(params, timeout)``) calls a method. A
timeout stops the wait, never the put or call (docs/embedding.md).

A view made with an ``origin`` (a part's views of its children carry their
block's mri) makes every put and call on that block's behalf
(:mod:`.origin`), from whatever thread, task or callback it is used.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from malcolm.core.errors import AbortedError, still_running

from .origin import on_behalf_of

if TYPE_CHECKING:
    from malcolm.core import Process


def _blocking_task() -> Any:
    from .blocking import current_blocking_task  # it imports this module

    return current_blocking_task()


def _result(
    fut: concurrent.futures.Future[Any],
    timeout: float | None,
    what: str,
    btask: Any = None,
) -> Any:
    """Wait for ``fut``; a timeout stops the wait, never the operation."""
    try:
        return fut.result(timeout)
    except concurrent.futures.TimeoutError:
        if fut.done():
            raise  # the operation itself raised a TimeoutError
        raise still_running(what, timeout) from None
    except concurrent.futures.CancelledError:
        if btask is None:
            raise
        raise AbortedError(f"{btask.part}: the phase was cancelled") from None


def _in_loop(process: Process) -> bool:
    try:
        return asyncio.get_running_loop() is process.loop
    except RuntimeError:
        return False


class FieldView:
    """One field of a block, seen through a process; writes through it are
    made on behalf of ``origin`` (an mri) if given."""

    def __init__(
        self, process: Process, mri: str, name: str, origin: str | None = None
    ) -> None:
        self.process = process
        self.mri = mri
        self.name = name
        self.origin = origin

    @property
    def path(self) -> list[str]:
        return [self.mri, self.name]

    @property
    def value(self) -> Any:
        return self.process.get_block(self.mri).attribute(self.name).value

    def put(self, value: Any, timeout: float | None = None) -> None:
        """Blocking put from a worker thread (waits for completion).

        After ``timeout`` seconds raises WaitTimeoutError; the put goes on.
        """
        self._check_thread("put")
        btask = _blocking_task()
        if btask is not None:  # in a hook function: cancelled with its phase
            btask.put(self.path, value, timeout)
            return
        fut = self.process.call_threadsafe(self.put_async, value)
        _result(fut, timeout, f"put {self.mri}.{self.name}")

    async def put_async(self, value: Any) -> None:
        with on_behalf_of(self.origin):
            await self.process.put(self.path, value)

    async def _post(self, params: dict[str, Any]) -> Any:
        with on_behalf_of(self.origin):
            return await self.process.post(self.path, params)

    def __call__(self, **params: Any) -> Any:
        """Call a method from a worker thread; returns what it returns."""
        return self.call(params)

    def call(
        self, params: Mapping[str, Any] | None = None, timeout: float | None = None
    ) -> Any:
        """Call a method from a worker thread with a dict of parameters.

        After ``timeout`` seconds raises WaitTimeoutError; the call goes on.
        """
        self._check_thread("call")
        params = dict(params or {})
        btask = _blocking_task()
        if btask is not None:  # in a hook function: cancelled with its phase
            fut = btask._submit(lambda: self._post(params))
            return _result(fut, timeout, f"{self.mri}.{self.name}()", btask)
        fut = self.process.call_threadsafe(self._post, params)
        return _result(fut, timeout, f"{self.mri}.{self.name}()")

    def _check_thread(self, what: str) -> None:
        if _in_loop(self.process):
            raise RuntimeError(
                f"{self.mri}.{self.name}.{what}() blocks: on the event loop use"
                " 'await ...put_async()', task.put() or process.post()"
            )

    def __hash__(self) -> int:
        return hash((self.mri, self.name))

    def __eq__(self, other: object) -> bool:
        return (
            isinstance(other, FieldView)
            and (other.mri, other.name) == (self.mri, self.name)
            and other.process is self.process
        )

    def __repr__(self) -> str:
        return f"<{self.mri}.{self.name}>"


class BlockView:
    """A block seen through a process: ``view.field`` gives a FieldView
    (writing on behalf of ``origin``, if given)."""

    def __init__(self, process: Process, mri: str, origin: str | None = None) -> None:
        self._process = process
        self.mri = mri
        self._origin = origin

    def __getattr__(self, name: str) -> FieldView:
        if name.startswith("_"):
            raise AttributeError(name)
        block = self._process.get_block(self.mri)
        if name not in block:
            raise AttributeError(f"{self.mri} has no field {name!r}")
        return FieldView(self._process, self.mri, name, self._origin)

    def __getitem__(self, name: str) -> FieldView:
        return self.__getattr__(name)

    def __repr__(self) -> str:
        return f"<BlockView {self.mri}>"

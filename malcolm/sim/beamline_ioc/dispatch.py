"""The simulated IOC's dispatcher: softioc's asyncio one, except for an
``on_update`` marked :func:`in_place`.

softioc hands every output record's ``on_update`` to its dispatcher; the
asyncio dispatcher runs it on the IOC's loop (one hop from the CA server's
thread to the loop's, a Task, then the completion back through EPICS'
callback thread), which took about 0.4 ms of a demand record's put here.
A demand whose ``on_update`` only shows the value on its readback
(``readback.set``, which softioc lets any thread call) needs none of that:
:class:`Dispatcher` runs such a function at once in the calling thread and
signals the completion, so the put completes after the readback's update
was requested, in the same order as before (the readback's processing and
the put's completion queued to EPICS' callback thread one after the other).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

from softioc.asyncio_dispatcher import AsyncioDispatcher

__all__ = ["Dispatcher", "in_place"]

log = logging.getLogger(__name__)


def in_place(func: Callable[[Any], Any]) -> Callable[[Any], Any]:
    """``func`` marked to run in the caller's thread (it must be safe there:
    a softioc record's ``set``)."""

    def run(value: Any) -> Any:
        return func(value)

    run.in_place = True  # type: ignore[attr-defined]
    return run


class Dispatcher(AsyncioDispatcher):
    """softioc's asyncio dispatcher; a function marked :func:`in_place` is
    run at once and its completion signalled."""

    def __call__(
        self,
        func: Callable[..., Any],
        func_args: tuple[Any, ...] = (),
        completion: Callable[..., Any] | None = None,
        completion_args: tuple[Any, ...] = (),
    ) -> None:
        if not getattr(func, "in_place", False):
            super().__call__(func, func_args, completion, completion_args)
            return
        try:
            func(*func_args)
        except Exception:
            log.exception("Exception when running an in-place on_update")
        finally:
            if completion is not None:
                completion(*completion_args)

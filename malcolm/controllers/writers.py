"""Who is writing a field: the origin of the puts in flight.

A manager holds some child attributes at values (Fixed and Follower rows)
and must tell its own changes from anyone else's. Every put carries an
origin, the mri of the block on whose behalf it is made, in the context
variable :data:`WRITER` (:mod:`malcolm.hooks.origin`): the controller sets
it while its hooks run, the parts' Tasks and views set it on every write
they make (from a hook, a worker thread, a thread of their own or a Task
subscription callback), and editor parts set it around their own writes.
A put made by anyone else (another client, a transport) carries None.

Each controller keeps the origins of the puts to its fields that are in
flight (:class:`PutsInFlight`); a change of a field is made by the origin of
the latest put to it still in flight, or by nobody (the hardware, the
block's own logic) if none is.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

from malcolm.hooks.origin import WRITER, writing_as

__all__ = ["WRITER", "PutsInFlight", "writing_as"]


class PutsInFlight:
    """The origins of the puts to one block's fields that have not finished."""

    def __init__(self) -> None:
        self._origins: dict[str, list[list[str | None]]] = {}

    def begin(self, field: str) -> list[str | None]:
        """Record a put to ``field`` by the current :data:`WRITER`; returns the
        entry to give :meth:`end` when it finishes (in a ``finally``)."""
        entry = [WRITER.get()]  # a fresh list: removed by identity
        stack = self._origins.get(field)
        if stack is None:
            self._origins[field] = [entry]
        else:
            stack.append(entry)
        return entry

    def end(self, field: str, entry: list[str | None]) -> None:
        """Forget the put :meth:`begin` recorded as ``entry``."""
        stack = self._origins.get(field)
        if stack is None:
            return
        if stack[-1] is entry:  # the common case: the latest put ends first
            stack.pop()
        else:
            for i, item in enumerate(stack):
                if item is entry:
                    del stack[i]
                    break
        if not stack:
            del self._origins[field]

    @contextlib.contextmanager
    def put(self, field: str) -> Iterator[None]:
        """Record a put to ``field`` by the current :data:`WRITER` until it ends
        (:meth:`begin` and :meth:`end` as a context manager)."""
        entry = self.begin(field)
        try:
            yield
        finally:
            self.end(field, entry)

    def writer_of(self, field: str) -> str | None:
        """The origin of the latest put to ``field`` still in flight, or None."""
        stack = self._origins.get(field)
        return stack[-1][0] if stack else None

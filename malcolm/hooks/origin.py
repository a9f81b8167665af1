"""The origin of a write: the mri of the block on whose behalf it is made.

Every put carries an origin in the context variable :data:`WRITER`; a put
made by nobody in particular (another client, a transport) carries None.
A controller sets it while its parts' hooks run; a part's :class:`Task`
and its views of other blocks (``self.child.x``) set it on every write
they make, from whatever thread or callback, so that a manager can tell
its own changes of a child attribute from anyone else's
(``malcolm.controllers.writers`` keeps the origins of the puts in flight).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from contextvars import ContextVar

#: the mri of the block on whose behalf the current code writes, or None
WRITER: ContextVar[str | None] = ContextVar("malcolm_writer", default=None)


@contextlib.contextmanager
def writing_as(origin: str | None) -> Iterator[None]:
    """Puts made (and tasks created) inside carry ``origin``."""
    token = WRITER.set(origin)
    try:
        yield
    finally:
        WRITER.reset(token)


def on_behalf_of(origin: str | None) -> contextlib.AbstractContextManager[None]:
    """:func:`writing_as` ``origin``, or, for None, the origin already set."""
    return writing_as(origin) if origin is not None else contextlib.nullcontext()

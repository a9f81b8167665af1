"""The scan an operation in progress planned, for the blocks it calls.

A manager's configure plans its scan once, then hands the same generator
(the very same object) to each child it validates and configures, all on
the loop inside its one operation. :data:`PLANNED` carries the generator
and the points built from it into that operation (a context variable: the
operation's task and every hook task and child call it starts copy it),
so a child planning the same object takes those points instead of reading
the generator again (its canonical JSON, its build cost). Only the same
object matches, never equal content: a generator another client sends is
a new object and is read as before. The data is not copied: between the
manager's planning and its children's, nothing but the manager's own
operation holds it (its caller awaits the call).

This module loads neither numpy nor scanspec.
"""

from __future__ import annotations

from contextvars import ContextVar, Token
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .points import ScanPoints

#: (generator, its points) of the scan the operation in progress planned
PLANNED: ContextVar[tuple[Any, ScanPoints] | None] = ContextVar(
    "malcolm_planned_scan", default=None
)


def planned_points(generator: Any) -> ScanPoints | None:
    """The points the operation in progress built from ``generator`` (this
    very object), or None."""
    planned = PLANNED.get()
    if planned is not None and planned[0] is generator:
        return planned[1]
    return None


def set_planned(
    generator: Any, points: ScanPoints
) -> Token[tuple[Any, ScanPoints] | None]:
    """Say that ``generator``'s points are ``points`` for what starts from
    here (give the token to ``PLANNED.reset`` when done)."""
    return PLANNED.set((generator, points))

"""A child's Validate done once inside its manager's configure.

A manager's configure runs its Validate phase (each child's ``validate()``)
and then its Configure phase (each child's ``configure()``) with the same
arguments, inside one operation. A child whose ``validate()`` gave its
arguments back unchanged need not run its Validate phase again when it is
configured with the same arguments inside that same operation: nothing
between the two but the manager's own phases, milliseconds apart.

:data:`CALLER` is the operation in progress of the block whose hooks are
running (a context variable: the operation's task and every hook task and
call it starts copy it), so a child called from it knows which one that
is. A ``validate()`` or ``configure()`` from anyone else (a client, GDA)
comes with no operation of a manager, or with another, and validates as
always.
"""

from __future__ import annotations

from collections.abc import Mapping
from contextvars import ContextVar
from dataclasses import dataclass
from typing import Any

#: the operation in progress of the block whose hooks run now (a token)
CALLER: ContextVar[object | None] = ContextVar("malcolm_caller_operation", default=None)


@dataclass(frozen=True)
class Validated:
    """Arguments a block's ``validate()`` gave back unchanged, inside its
    caller's operation ``caller``, and what its Validate phase returned."""

    caller: object
    params: dict[str, Any]
    results: dict[str, Any]

    def holds_for(self, caller: object | None, params: Mapping[str, Any]) -> bool:
        """Whether a configure with ``params`` inside ``caller`` is of the
        arguments validated here, in the same operation of the caller."""
        return (
            caller is not None and caller is self.caller and same(self.params, params)
        )


def same(a: Mapping[str, Any], b: Mapping[str, Any]) -> bool:
    """Whether two argument dicts hold the same values: the very objects,
    or equal plain values (numbers, text, lists of them); anything whose
    ``==`` is not a plain answer (an array) counts as different."""
    if a.keys() != b.keys():
        return False
    for k, v in a.items():
        w = b[k]
        if v is w:
            continue
        try:
            equal = v == w
        except Exception:
            return False
        if equal is not True:
            return False
    return True

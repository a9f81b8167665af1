"""Client side of deltas: apply a list of changes (interop.md §3) to plain data."""

from __future__ import annotations

import copy
from collections.abc import Sequence
from typing import Any

from .errors import BadValueError, NotFoundError


def apply_changes(data: Any, changes: Sequence[Sequence[Any]]) -> Any:
    """Apply delta ``changes`` to plain ``data`` and return the result.

    Each change is ``[path, value]`` (set the value at path, adding the last
    key if it is new) or ``[path]`` (delete it); ``[[], value]`` replaces the
    whole and ``[[]]`` deletes it (the result is then None). Dicts in
    ``data`` are changed in place; values are copied in, so that later
    changes never alter what the sender (or another subscriber) holds.
    """
    for change in changes:
        if not isinstance(change, Sequence) or len(change) not in (1, 2):
            raise BadValueError(f"a change is [path, value] or [path], got {change!r}")
        path = list(change[0])
        if not path:
            data = copy.deepcopy(change[1]) if len(change) == 2 else None
            continue
        parent = data
        for i, key in enumerate(path[:-1]):
            if not isinstance(parent, dict) or key not in parent:
                raise NotFoundError(
                    f"change {_dotted(path)}: no {_dotted(path[: i + 1])!r}"
                )
            parent = parent[key]
        if not isinstance(parent, dict):
            raise NotFoundError(
                f"change {_dotted(path)}: {_dotted(path[:-1])!r} is not a structure"
            )
        last = path[-1]
        if len(change) == 2:
            parent[last] = copy.deepcopy(change[1])
        elif last in parent:
            del parent[last]
        else:
            raise NotFoundError(f"change {_dotted(path)}: nothing to delete")
    return data


def _dotted(path: Sequence[Any]) -> str:
    return ".".join(map(str, path))

"""Read a file once per process: keep what was made from it while it is unchanged.

Models (:mod:`malcolm.fsm.loader`) and block definitions
(:mod:`malcolm.config.definitions`) are parsed once and the result shared by
every block that uses them. A :class:`Snapshot` says what a file held when it
was read; a :class:`FileCache` hands a kept value back only while its file
still holds that.

A file counts as unchanged if its stamp (modification time, size, inode) is
the same and the file was last modified well before it was read; otherwise
(a file written again within the file system's timestamp granularity keeps
its stamp) its bytes are compared, as git does for the index entries it
calls "racy".
"""

from __future__ import annotations

import os
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Generic, TypeVar

__all__ = ["FileCache", "Snapshot"]

V = TypeVar("V")

#: a stamp this close to the time of reading is not trusted on its own
RACY_NS = 2_000_000_000

Stamp = tuple[int, int, int]  # st_mtime_ns, st_size, st_ino


def _stamp(path: Path) -> Stamp | None:
    try:
        st = os.stat(path)
    except OSError:
        return None
    return (st.st_mtime_ns, st.st_size, st.st_ino)


@dataclass
class Snapshot:
    """What ``path`` held when it was read: its stamp and its bytes."""

    path: Path
    stamp: Stamp
    taken_ns: int
    content: bytes

    @classmethod
    def take(cls, path: str | os.PathLike[str]) -> Snapshot | None:
        """A snapshot of ``path`` now; None if it cannot be read."""
        path = Path(path)
        taken = time.time_ns()
        stamp = _stamp(path)
        try:
            content = path.read_bytes()
        except OSError:
            return None
        if stamp is None:
            return None
        return cls(path, stamp, taken, content)

    def unchanged(self) -> bool:
        """Whether the file still holds what it held when the snapshot was taken."""
        stamp = _stamp(self.path)
        if stamp is None:
            return False
        if stamp == self.stamp and stamp[0] < self.taken_ns - RACY_NS:
            return True
        try:
            same = self.path.read_bytes() == self.content
        except OSError:
            return False
        if same:  # trust the new stamp from now on
            self.stamp, self.taken_ns = stamp, time.time_ns()
        return same


class FileCache(Generic[V]):
    """Values made from files, by key, kept while their file is unchanged.

    At most ``size`` are kept: the least recently used goes first. ``lock``
    (re-entrant) is for callers whose loading takes several steps;
    :meth:`get` and :meth:`put` take it themselves.
    """

    def __init__(self, size: int = 512) -> None:
        self.size = size
        self.lock = threading.RLock()
        self._entries: dict[Any, tuple[Snapshot, V]] = {}

    def get(self, key: Any) -> V | None:
        """The value kept for ``key`` if its file is unchanged, else None."""
        with self.lock:
            entry = self._entries.get(key)
            if entry is None:
                return None
            del self._entries[key]
            if not entry[0].unchanged():
                return None
            self._entries[key] = entry  # now the most recently used
            return entry[1]

    def put(self, key: Any, snapshot: Snapshot, value: V) -> None:
        """Keep ``value``, made from the file as ``snapshot`` saw it."""
        with self.lock:
            self._entries.pop(key, None)
            self._entries[key] = (snapshot, value)
            while len(self._entries) > self.size:
                del self._entries[next(iter(self._entries))]

    def clear(self) -> None:
        """Forget everything: the next load reads its file again."""
        with self.lock:
            self._entries.clear()

    def __len__(self) -> int:
        return len(self._entries)

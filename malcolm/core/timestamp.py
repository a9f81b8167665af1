"""TimeStamp (the EPICS time_t structure)."""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, ClassVar


@dataclass(frozen=True)
class TimeStamp:
    """Seconds and nanoseconds past the POSIX epoch, plus a user tag."""

    secondsPastEpoch: int = 0  # noqa: N815 (wire name)
    nanoseconds: int = 0
    userTag: int = 0  # noqa: N815

    typeid: ClassVar[str] = "time_t"
    zero: ClassVar[TimeStamp]

    @classmethod
    def now(cls) -> TimeStamp:
        # made as __init__ would, without the frozen dataclass's setattr per
        # field (half the cost; every change of every attribute takes one)
        seconds, nanoseconds = divmod(time.time_ns(), 1_000_000_000)
        stamp = object.__new__(cls)
        stamp.__dict__.update(
            secondsPastEpoch=seconds, nanoseconds=nanoseconds, userTag=0
        )
        return stamp

    @classmethod
    def now_and_dict(cls) -> tuple[TimeStamp, dict[str, Any]]:
        """``now()`` and its ``to_dict()``, made in one call (every change
        of an attribute takes one, a method's took and returned one each)."""
        seconds, nanoseconds = divmod(time.time_ns(), 1_000_000_000)
        stamp = object.__new__(cls)
        stamp.__dict__.update(
            secondsPastEpoch=seconds, nanoseconds=nanoseconds, userTag=0
        )
        return stamp, {
            "typeid": cls.typeid,
            "secondsPastEpoch": seconds,
            "nanoseconds": nanoseconds,
            "userTag": 0,
        }

    def to_time(self) -> float:
        return self.secondsPastEpoch + self.nanoseconds * 1e-9

    def to_dict(self) -> dict[str, Any]:
        return {
            "typeid": self.typeid,
            "secondsPastEpoch": self.secondsPastEpoch,
            "nanoseconds": self.nanoseconds,
            "userTag": self.userTag,
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> TimeStamp:
        return cls(
            int(d.get("secondsPastEpoch", 0)),
            int(d.get("nanoseconds", 0)),
            int(d.get("userTag", 0)),
        )


TimeStamp.zero = TimeStamp()

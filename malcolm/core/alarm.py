"""Alarm (the EPICS alarm_t structure)."""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum
from typing import Any, ClassVar


class AlarmSeverity(IntEnum):
    NO_ALARM = 0
    MINOR_ALARM = 1
    MAJOR_ALARM = 2
    INVALID_ALARM = 3
    UNDEFINED_ALARM = 4


class AlarmStatus(IntEnum):
    NO_STATUS = 0
    DEVICE_STATUS = 1
    DRIVER_STATUS = 2
    RECORD_STATUS = 3
    DB_STATUS = 4
    CONF_STATUS = 5
    UNDEFINED_STATUS = 6
    CLIENT_STATUS = 7


@dataclass(frozen=True)
class Alarm:
    """Severity, status and message of a value, as in EPICS ``alarm_t``."""

    severity: AlarmSeverity = AlarmSeverity.NO_ALARM
    status: AlarmStatus = AlarmStatus.NO_STATUS
    message: str = ""

    typeid: ClassVar[str] = "alarm_t"
    ok: ClassVar[Alarm]

    @classmethod
    def minor(cls, message: str) -> Alarm:
        return cls(AlarmSeverity.MINOR_ALARM, AlarmStatus.DEVICE_STATUS, message)

    @classmethod
    def major(cls, message: str) -> Alarm:
        return cls(AlarmSeverity.MAJOR_ALARM, AlarmStatus.DEVICE_STATUS, message)

    @classmethod
    def invalid(cls, message: str) -> Alarm:
        return cls(AlarmSeverity.INVALID_ALARM, AlarmStatus.DEVICE_STATUS, message)

    @classmethod
    def disconnected(cls, message: str) -> Alarm:
        return cls(AlarmSeverity.INVALID_ALARM, AlarmStatus.CLIENT_STATUS, message)

    def to_dict(self) -> dict[str, Any]:
        return {
            "typeid": self.typeid,
            "severity": int(self.severity),
            "status": int(self.status),
            "message": self.message,
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Alarm:
        return cls(
            AlarmSeverity(int(d.get("severity", 0))),
            AlarmStatus(int(d.get("status", 0))),
            str(d.get("message", "")),
        )


Alarm.ok = Alarm()

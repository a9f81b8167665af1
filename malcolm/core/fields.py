"""Attribute and Method: the fields of a block."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from threading import get_ident
from time import time_ns
from typing import TYPE_CHECKING, Any

from .alarm import Alarm
from .errors import BadValueError
from .metas import Meta, MethodMeta, TableMeta, plain
from .timestamp import TimeStamp

if TYPE_CHECKING:
    from .block import Block

Change = list  # [path: list[str], value] or [path] for a delete

TABLE_TYPEID = "malcolm:core/Table:1.0"

#: what plain() gives back as it is
_PLAIN = frozenset({float, int, str, bool, type(None)})


class Field:
    """Something with a name that lives in a block and reports its changes."""

    typeid = ""

    def __init__(self, name: str) -> None:
        self.name = name
        self.block: Block | None = None

    def _notify(self, changes: list[Change]) -> None:
        if self.block is not None:
            self.block.notify(changes)

    def _off_loop(self, func: Callable[..., Any], *args: Any) -> bool:
        """True if ``func(*args)``, a change of this field called off its
        process's loop thread, was run on the loop instead (see
        :mod:`malcolm.core.threads`); False: go ahead here."""
        block = self.block
        owner = block.owner if block is not None else None
        if owner is None or owner.here():
            return False
        done, _ = owner.elsewhere(f"{block.mri}.{self.name}", func, *args)
        return done

    def to_dict(self) -> dict[str, Any]:
        raise NotImplementedError


class Attribute(Field):
    """A value with alarm, timeStamp and meta.

    ``put_handler`` (set by the part that owns the attribute) is what an
    external put calls; it may be a plain or an async function. Without one,
    a put of a writeable attribute just sets the value.
    """

    def __init__(
        self,
        name: str,
        meta: Meta,
        value: Any = None,
        alarm: Alarm = Alarm.ok,
        timeStamp: TimeStamp | None = None,  # noqa: N803
        put_handler: Callable[[Any], Any] | None = None,
    ) -> None:
        super().__init__(name)
        self.meta = meta
        self.value = meta.validate(meta.default() if value is None else value)
        self.alarm = alarm
        self.timeStamp = timeStamp or TimeStamp.now()
        self.put_handler = put_handler

    @property
    def typeid(self) -> str:  # type: ignore[override]
        return self.meta.nt_typeid

    def validate(self, value: Any) -> Any:
        """Return the canonical value, or raise BadValueError naming block.field."""
        try:
            return self.meta.validate(value)
        except BadValueError as e:
            raise BadValueError(f"{self.path_name}: {e}") from None

    @property
    def path_name(self) -> str:
        return f"{self.block.mri}.{self.name}" if self.block else self.name

    def set_value(
        self,
        value: Any,
        alarm: Alarm | None = None,
        timeStamp: TimeStamp | None = None,  # noqa: N803
        validate: bool = True,
    ) -> None:
        """Set the value (and optionally alarm); publish one delta."""
        # the common case (on the loop, or no loop yet) checked in line: this
        # runs for every change of every attribute
        block = self.block
        owner = block.owner if block is not None else None
        if owner is not None and owner.thread != get_ident():  # here(), in line
            if self._off_loop(self.set_value, value, alarm, timeStamp, validate):
                return
        if validate:
            value = self.validate(value)
        self.value = value
        if timeStamp is None:
            self.timeStamp, stamp_dict = TimeStamp.now_and_dict()
        else:
            self.timeStamp = timeStamp
            stamp_dict = timeStamp.to_dict()
        name = self.name
        # a scalar is its own plain data (value_dict's answer, without a call)
        plain_value = value if type(value) in _PLAIN else self.value_dict()
        changes: list[Change] = [[[name, "value"], plain_value]]
        if alarm is not None and alarm != self.alarm:
            self.alarm = alarm
            changes.append([[name, "alarm"], alarm.to_dict()])
        changes.append([[name, "timeStamp"], stamp_dict])
        if block is not None:
            block.notify(changes)

    def set_alarm(self, alarm: Alarm) -> None:
        """Set the alarm (and timeStamp) alone; publish one delta."""
        if self._off_loop(self.set_alarm, alarm):
            return
        if alarm != self.alarm:
            self.alarm = alarm
            self.timeStamp = TimeStamp.now()
            self._notify(
                [
                    [[self.name, "alarm"], alarm.to_dict()],
                    [[self.name, "timeStamp"], self.timeStamp.to_dict()],
                ]
            )

    def set_writeable(self, writeable: bool) -> None:
        if self._off_loop(self.set_writeable, writeable):
            return
        if writeable != self.meta.writeable:
            self.meta.writeable = writeable
            self._notify([[[self.name, "meta", "writeable"], writeable]])

    def set_meta(self, meta: Meta, value: Any = None) -> None:
        """Replace the meta (e.g. with the limits a channel reported), and the
        value with ``value`` if given; publish one delta.

        The (new or current) value must fit the new meta: if it does not,
        BadValueError names the attribute and nothing changes.
        """
        if self._off_loop(self.set_meta, meta, value):
            return
        new = self.value if value is None else value
        try:
            new = meta.validate(new)
        except BadValueError as e:
            raise BadValueError(f"{self.path_name}: {e}") from None
        self.meta = meta
        changes: list[Change] = [[[self.name, "meta"], meta.to_dict()]]
        if isinstance(meta, TableMeta):
            changes.append([[self.name, "labels"], self.to_dict()["labels"]])
        if value is not None or new != self.value:
            self.value = new
            self.timeStamp = TimeStamp.now()
            changes.append([[self.name, "value"], self.value_dict()])
            changes.append([[self.name, "timeStamp"], self.timeStamp.to_dict()])
        self._notify(changes)

    def value_dict(self) -> Any:
        """The value as plain data, as it appears in ``to_dict()["value"]``."""
        if isinstance(self.meta, TableMeta):
            value = dict(plain(self.value))
            value["typeid"] = TABLE_TYPEID
            return value
        return plain(self.value)

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {"typeid": self.typeid}
        if isinstance(self.meta, TableMeta):
            d["labels"] = [m.label or k for k, m in self.meta.elements.items()]
        d["value"] = self.value_dict()
        d["alarm"] = self.alarm.to_dict()
        d["timeStamp"] = self.timeStamp.to_dict()
        d["meta"] = self.meta.to_dict()
        return d


@dataclass
class MethodLog:
    """The arguments a method took, or what it returned, with alarm and time."""

    value: dict[str, Any] = field(default_factory=dict)
    present: list[str] = field(default_factory=list)
    alarm: Alarm = Alarm.ok
    timeStamp: TimeStamp = TimeStamp.zero  # noqa: N815

    typeid = "malcolm:core/MethodLog:1.0"

    def to_dict(self) -> dict[str, Any]:
        return _log_dict(self.value, self.present, self.alarm, self.timeStamp.to_dict())

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> MethodLog:
        return cls(
            dict(d.get("value", {})),
            list(d.get("present", [])),
            Alarm.from_dict(d.get("alarm", {})),
            TimeStamp.from_dict(d.get("timeStamp", {})),
        )


#: Alarm.ok as plain data, copied for each log that has it (most)
_OK_ALARM = Alarm.ok.to_dict()


def _log_dict(
    value: Any, present: list[str], alarm: Alarm, stamp: dict[str, Any]
) -> dict[str, Any]:
    """A MethodLog as plain data (its to_dict), from its parts (its stamp's
    already plain)."""
    if type(value) is dict and _PLAIN.issuperset(map(type, value.values())):
        value = dict(value)  # plain() of scalars (most arguments), in C
    else:
        value = plain(value)
    return {
        "typeid": MethodLog.typeid,
        "value": value,
        "present": list(present),
        "alarm": dict(_OK_ALARM) if alarm is Alarm.ok else alarm.to_dict(),
        "timeStamp": stamp,
    }


def _new_log(value: dict[str, Any], alarm: Alarm) -> tuple[MethodLog, Any]:
    """A MethodLog of ``value`` (a dict of its own: all its keys present)
    with ``alarm``, stamped now, and what a change publishes of it: the log
    itself when its arguments are all scalars (most; a subscriber that wants
    plain data gets its ``to_dict()``, see :func:`plain_changes`), else its
    plain data, made now (a list the method keeps may change later). Twice
    per call of every method, so made without the dataclasses' ``__init__``."""
    seconds, nanoseconds = divmod(time_ns(), 1_000_000_000)
    stamp = object.__new__(TimeStamp)  # TimeStamp.now(), in line
    stamp.__dict__.update(secondsPastEpoch=seconds, nanoseconds=nanoseconds, userTag=0)
    log = object.__new__(MethodLog)
    log.__dict__.update(value=value, present=list(value), alarm=alarm, timeStamp=stamp)
    if _PLAIN.issuperset(map(type, value.values())):
        return log, log
    return log, _log_dict(value, list(value), alarm, stamp.to_dict())


def plain_changes(changes: list[Change]) -> list[Change]:
    """``changes`` as plain data: a MethodLog a method published as it is
    (see :func:`_new_log`) replaced by its ``to_dict()``; ``changes`` itself
    if none is (a new list otherwise, the others' changes as they are)."""
    for change in changes:
        if len(change) == 2 and type(change[1]) is MethodLog:
            return [
                [c[0], c[1].to_dict()] if len(c) == 2 and type(c[1]) is MethodLog else c
                for c in changes
            ]
    return changes


class Method(Field):
    """A callable field: takes arguments described by its meta, returns a map.

    ``handler`` receives the validated arguments as keywords and may be a
    plain or an async function.
    """

    typeid = "malcolm:core/Method:1.1"

    def __init__(
        self,
        name: str,
        meta: MethodMeta,
        handler: Callable[..., Any] | None = None,
    ) -> None:
        super().__init__(name)
        self.meta = meta
        self.handler = handler
        self.took = MethodLog()
        self.returned = MethodLog()
        #: the arguments' plan of its meta (malcolm.core.callplan), made by
        #: the first call; a call with another meta (or one changed) makes anew
        self.args_plan: Any = None

    def set_took(
        self,
        args: Mapping[str, Any],
        hold: Callable[[str, Change, list[str]], None] | None = None,
    ) -> None:
        """Log the arguments of a call beginning and publish them; ``hold``
        (the block's process's :meth:`~malcolm.core.Process.hold`): published
        through it, to go with this method's returned if nothing else is
        published first."""
        # on the loop (the common case) checked in line, as set_value does:
        # once per call of every method
        block = self.block
        owner = block.owner if block is not None else None
        if owner is not None and owner.thread != get_ident():  # here(), in line
            if self._off_loop(self.set_took, args):
                return
        self.took, data = _new_log(dict(args), Alarm.ok)
        if block is not None:
            if hold is None:
                block.notify([[[self.name, "took"], data]])
            else:
                hold(block.mri, [[self.name, "took"], data], [self.name, "returned"])

    def set_returned(self, value: Mapping[str, Any] | None, alarm: Alarm) -> None:
        block = self.block
        owner = block.owner if block is not None else None
        if owner is not None and owner.thread != get_ident():  # here(), in line
            if self._off_loop(self.set_returned, value, alarm):
                return
        self.returned, data = _new_log(dict(value) if value else {}, alarm)
        if block is not None:
            block.notify([[[self.name, "returned"], data]])

    def set_writeable(self, writeable: bool) -> None:
        if self._off_loop(self.set_writeable, writeable):
            return
        if writeable != self.meta.writeable:
            self.meta.writeable = writeable
            self._notify([[[self.name, "meta", "writeable"], writeable]])

    def to_dict(self) -> dict[str, Any]:
        return {
            "typeid": self.typeid,
            "took": self.took.to_dict(),
            "returned": self.returned.to_dict(),
            "meta": self.meta.to_dict(),
        }

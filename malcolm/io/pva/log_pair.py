"""A call's took and returned set into a channel's update by one function.

When a method does not wait, the core publishes its ``took`` and
``returned`` as one batch of two :class:`~malcolm.core.MethodLog`\\ s
(``Process.subscribe``'s ``logs``). :func:`compile_log_pair` makes, once per
channel and method, a generated function ``pair(value, changes) -> bool``
that does what the two logs' setters (:mod:`malcolm.io.pva.setters`,
``_log_setter``) and the channel's fast path (``_Channel._apply_fast``) do
for them, every leaf in line: each log's arguments by its value's setter,
its ``present`` compared to what it holds, its alarm passed over when it is
the very ``Alarm`` last set, its timeStamp's leaves compared to what they
hold (a new one checked to be an int), and each recorded in the channel's
pending changes. Leaves are marked and recorded in the channel's ``last``
as those setters would. False (anything else: a log not a ``MethodLog``,
data that does not fit): the caller clears ``last`` and takes the channel's
general path; so does an error it raises (a log whose timeStamp is not a
``TimeStamp``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from p4p import Value

from malcolm.core import MethodLog

from .convert import Spec
from .setters import compile_setter

__all__ = ["LogPair", "compile_log_pair"]

LogPair = Callable[[Value, list[list[Any]]], bool]

_TIME_T = (
    "S",
    "time_t",
    (("secondsPastEpoch", "l"), ("nanoseconds", "i"), ("userTag", "i")),
)

_PART = """\
    log = {log}
    if not SET_V{i}(value, log.value):
        return False
    present = log.present
    if present != GET({present!r}):
        if type(present) is not list or not all(type(x) is str for x in present):
            return False
        value[{present!r}] = present
        last[{present!r}] = list(present)
    alarm = log.alarm
    if alarm is not GET({alarm!r}):
        if not SET_A{i}(value, alarm.to_dict()):
            return False
        last[{alarm!r}] = alarm
    stamp = log.timeStamp
    x = stamp.secondsPastEpoch
    if x != GET({s!r}):
        if type(x) is not int:
            return False
        value[{s!r}] = last[{s!r}] = x
    x = stamp.nanoseconds
    if x != GET({ns!r}):
        if type(x) is not int:
            return False
        value[{ns!r}] = last[{ns!r}] = x
    x = stamp.userTag
    if x != GET({tag!r}):
        if type(x) is not int:
            return False
        value[{tag!r}] = last[{tag!r}] = x
"""

_PENDING = """\
    try:
        del pending[{key!r}]
    except KeyError:
        pass
    pending[{key!r}] = {log}
"""


def compile_log_pair(
    took: tuple[Spec, tuple[str, ...]],
    returned: tuple[Spec, tuple[str, ...]],
    last: dict[str, Any],
    pending: dict[tuple[str, ...], Any],
) -> LogPair | None:
    """The pair function of a method's ``took`` and ``returned``, each given
    as (its spec, its path in the channel); ``last`` and ``pending`` are the
    channel's (its record of what leaves hold, its changes not yet applied
    to its data). None if either is not the MethodLog the core makes."""
    ns: dict[str, Any] = {
        "MethodLog": MethodLog,
        "last": last,
        "GET": last.get,
        "pending": pending,
    }
    body = [
        "def pair(value, changes):",
        "    (_, took), (_, returned) = changes",
        "    if type(took) is not MethodLog or type(returned) is not MethodLog:",
        "        return False",
    ]
    tail = []
    for i, (log, (spec, where)) in enumerate((("took", took), ("returned", returned))):
        if not isinstance(spec, tuple) or spec[1] != MethodLog.typeid:
            return None
        parts = dict(spec[2])
        if parts.get("present") != "as" or parts.get("timeStamp") != _TIME_T:
            return None  # not the MethodLog the core makes
        dotted = ".".join(where)
        ns[f"SET_V{i}"] = compile_setter(parts["value"], f"{dotted}.value", True, last)
        ns[f"SET_A{i}"] = compile_setter(parts["alarm"], f"{dotted}.alarm", last=last)
        stamp = f"{dotted}.timeStamp"
        body.append(
            _PART.format(
                log=log,
                i=i,
                present=f"{dotted}.present",
                alarm=f"{dotted}.alarm",
                s=f"{stamp}.secondsPastEpoch",
                ns=f"{stamp}.nanoseconds",
                tag=f"{stamp}.userTag",
            )
        )
        tail.append(_PENDING.format(key=where, log=log))
    source = "\n".join([*body, *tail, "    return True\n"])
    exec(compile(source, f"<log pair {took[1][0]}>", "exec"), ns)
    pair: LogPair = ns["pair"]
    return pair

"""Precompiled assignment of a change's data into a channel's ``Value``.

A channel's monitor update is a ``Value`` of the channel's type in which
only the changed leaves are set. :func:`compile_setter` turns the type spec
of one field (:func:`malcolm.io.pva.convert.spec_at`) into a function
``setter(value, data) -> bool`` that checks ``data`` still fits that type
(as :func:`~malcolm.io.pva.convert.fits` does) and sets its leaves (as
:func:`~malcolm.io.pva.convert.assign` does), walking the spec once when
compiled instead of once per change: a structure's setter is generated
Python source, every leaf checked and set in line. False means the data does not fit:
the caller drops the half-filled ``Value`` and takes the general path.

Given a channel's ``last`` dict (leaf name -> the value it was last set
to), a setter leaves a scalar leaf unmarked when it is given the value it
already holds (the same int, str or bool, a float other than zero, a list
of str equal to it): the update carries only what changed (an alarm or a
timeStamp's seconds mostly stay, only its nanoseconds move), which costs
less to set, to post and to send. The dict is the channel's, shared by all
its setters (two setters may set one leaf); whoever sets the channel's
value another way clears it. A structure of scalar leaves that does not
change every time (an alarm, a method's arguments; not a timeStamp) is
recorded there whole too: given one equal to it (its float zeros of the
same sign), its setter passes over it in one comparison; a setter that
sets one of its leaves alone drops the record.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from p4p import Value

from malcolm.core import MethodLog

from .convert import STRUCTURE, Spec, _fill, fits

__all__ = ["Setter", "compile_setter"]

Setter = Callable[[Value, Any], bool]

_METHOD_LOG = "malcolm:core/MethodLog:1.0"

# the Python types that fit a scalar code as they are (bool is not an int here)
_EXACT: dict[str, tuple[type, ...]] = {
    **{code: (int,) for code in "bBhHiIlL"},
    "f": (float, int),
    "d": (float, int),
    "s": (str,),
    "?": (bool,),
}


def compile_setter(
    spec: Spec, dotted: str, subset: bool = False, last: dict[str, Any] | None = None
) -> Setter:
    """A setter of the field ``dotted`` (``""``: the whole value) of type
    ``spec``; ``subset``: a structure may hold fewer fields (a MethodLog's
    value); ``last``: the channel's record of what its leaves hold, to leave
    unchanged ones unmarked (see the module's docstring).

    A structure's setter is one generated function that checks and sets
    every leaf in line (a change's data is a few nested dicts: a timeStamp,
    an alarm, a MethodLog), with no call per field."""
    if not isinstance(spec, tuple):
        return _leaf_setter(spec, dotted, last)
    if spec[1] == _METHOD_LOG and not subset:
        return _log_setter(spec, dotted, last, _struct_setter(spec, dotted, last))
    return _struct_setter(spec, dotted, last, subset)


def _struct_setter(
    spec: Spec, dotted: str, last: dict[str, Any] | None, subset: bool = False
) -> Setter:
    """The generated setter of a structure's plain data (see compile_setter)."""
    gen = _Generator(last is not None)
    body = gen.struct(spec, dotted, subset, "data", 1)
    source = "def setter(value, data):\n" + "".join(body) + "    return True\n"
    namespace: dict[str, Any] = dict(gen.constants)
    namespace["last"] = last
    exec(compile(source, f"<setter {dotted or 'value'}>", "exec"), namespace)
    setter: Setter = namespace["setter"]
    return setter


_MISSING = object()


def _log_setter(
    spec: Spec, dotted: str, last: dict[str, Any] | None, general: Setter
) -> Setter:
    """A MethodLog's setter: given the core's :class:`MethodLog` itself (what
    a method publishes, see ``malcolm.core.fields._new_log``), its parts are
    set from its attributes with no plain data made: its value by the
    value's own setter (a structure of the method's takes or returns, fewer
    fields allowed), its ``present`` compared to what it holds, its alarm
    passed over when it is the very one last set (an :class:`Alarm` is
    frozen: the core's logs mostly hold ``Alarm.ok``), its timeStamp's ints
    compared to what they hold. Leaves are marked and recorded in ``last``
    as ``general`` (the setter of its plain data, given anything else)
    would; a part that does not fit as it is goes to ``general`` whole."""
    if last is None:

        def unremembered(value: Value, data: Any) -> bool:
            if type(data) is MethodLog:
                data = data.to_dict()
            return general(value, data)

        return unremembered
    parts = dict(spec[2])
    prefix = f"{dotted}." if dotted else ""
    set_args = compile_setter(parts["value"], f"{prefix}value", True, last)
    set_alarm = compile_setter(parts["alarm"], f"{prefix}alarm", last=last)
    where_present, where_alarm = f"{prefix}present", f"{prefix}alarm"
    stamp = f"{prefix}timeStamp"
    where_s, where_ns, where_tag = (
        f"{stamp}.secondsPastEpoch",
        f"{stamp}.nanoseconds",
        f"{stamp}.userTag",
    )
    if parts["present"] != "as" or parts["timeStamp"] != (
        "S",
        "time_t",
        (("secondsPastEpoch", "l"), ("nanoseconds", "i"), ("userTag", "i")),
    ):  # not the MethodLog the core makes: its plain data, always

        def other(value: Value, data: Any) -> bool:
            if type(data) is MethodLog:
                data = data.to_dict()
            return general(value, data)

        return other

    def log_setter(value: Value, data: Any) -> bool:
        if type(data) is not MethodLog:
            return general(value, data)
        if not set_args(value, data.value):
            return False
        present = data.present
        if present != last.get(where_present):
            if type(present) is not list or not all(type(x) is str for x in present):
                return general(value, data.to_dict())
            value[where_present] = present
            last[where_present] = list(present)
        alarm = data.alarm
        if alarm is not last.get(where_alarm):
            if not set_alarm(value, alarm.to_dict()):
                return False
            last[where_alarm] = alarm  # (the leaves hold it: frozen)
        stamp = data.timeStamp
        seconds, nanoseconds, tag = (
            stamp.secondsPastEpoch,
            stamp.nanoseconds,
            stamp.userTag,
        )
        if seconds != last.get(where_s):
            if type(seconds) is not int:
                return general(value, data.to_dict())
            value[where_s] = last[where_s] = seconds
        if nanoseconds != last.get(where_ns):
            if type(nanoseconds) is not int:
                return general(value, data.to_dict())
            value[where_ns] = last[where_ns] = nanoseconds
        if tag != last.get(where_tag):
            if type(tag) is not int:
                return general(value, data.to_dict())
            value[where_tag] = last[where_tag] = tag
        return True

    return log_setter


def _leaf_setter(spec: Spec, dotted: str, last: dict[str, Any] | None) -> Setter:
    exact = _EXACT.get(spec)
    if exact is not None:
        if last is not None:
            parent = dotted.rpartition(".")[0]  # its structure's record

            def remembered(value: Value, data: Any) -> bool:
                if type(data) in exact:
                    # new: not equal (_MISSING is unequal to anything), or a
                    # zero that may be a float's (0.0 == -0.0)
                    before = last.get(dotted, _MISSING)
                    if data != before or (
                        not data and (type(data) is float or type(before) is float)
                    ):
                        value[dotted] = last[dotted] = data
                        last.pop(parent, None)
                    return True
                if fits(spec, data):
                    last.pop(dotted, None)
                    last.pop(parent, None)
                    value[dotted] = _fill(spec, data)
                    return True
                return False

            return remembered

        def scalar(value: Value, data: Any) -> bool:
            if type(data) in exact:
                value[dotted] = data
                return True
            if fits(spec, data):  # numpy scalars and the like
                value[dotted] = _fill(spec, data)
                return True
            return False

        return scalar

    def general(value: Value, data: Any) -> bool:
        if fits(spec, data):
            if last is not None:
                last.pop(dotted, None)
                last.pop(dotted.rpartition(".")[0], None)
            value[dotted] = _fill(spec, data)
            return True
        return False

    return general


#: structures whose leaves change every time: no record of them is kept
_ALWAYS_NEW = frozenset({"time_t"})

#: structures the core makes of ints (a timeStamp): a leaf equal to what it
#: holds is passed over before its type is checked
_COMPARED_FIRST = frozenset({"time_t"})


def _recordable(spec: Spec) -> bool:
    """Whether a structure's setter keeps a record of the whole structure as
    last set (with ``last``): only for one of scalar leaves (its float
    zeros compared by their sign too: ``0.0 == -0.0``) that does not change
    every time (a timeStamp)."""
    if spec[1] in _ALWAYS_NEW:
        return False
    return all(isinstance(sub, str) and sub in _EXACT for _, sub in spec[2])


class _Generator:
    """Writes the lines of a structure's setter; its constants (names,
    specs, the fallbacks) go in the function's globals as ``c<n>``."""

    def __init__(self, remember: bool = False) -> None:
        self.constants: dict[str, Any] = {
            "fits": fits,
            "_fill": _fill,
            "MISSING": _MISSING,
            "UNRECORDED": (_MISSING, None),
        }
        self.names = 0
        self.remember = remember  # with the channel's ``last`` (see the module)

    def const(self, value: Any) -> str:
        name = f"c{len(self.constants)}"
        self.constants[name] = value
        return name

    def var(self) -> str:
        self.names += 1
        return f"d{self.names}"

    def struct(
        self, spec: Spec, dotted: str, subset: bool, data: str, depth: int
    ) -> list[str]:
        pad = "    " * depth
        names = tuple(k for k, _ in spec[2])
        log = spec[1] == _METHOD_LOG
        lines: list[str] = []
        record = self.remember and _recordable(spec)
        floats = False
        if record:
            # the whole structure as last set (its shape checked then): equal,
            # nothing to check or set; a float zero equal to the one recorded
            # may differ in sign
            before = self.var()
            floats = any(sub in ("f", "d") for _, sub in spec[2])
            if floats:
                # recorded with its text: equal dicts of the same text hold
                # float zeros of the same sign
                lines += [
                    f"{pad}{before} = last.get({dotted!r}, UNRECORDED)\n",
                    f"{pad}if {data} != {before}[0] or str({data}) != {before}[1]:\n",
                ]
            else:  # (None, what is not recorded, is unequal to a dict)
                lines.append(f"{pad}if {data} != last.get({dotted!r}):\n")
            depth += 1
            pad += "    "
        keys, typeid = self.var(), self.var()
        typed, plain = self.const(("typeid", *names)), self.const(names)
        fields = [self.var() for _ in names]
        unpacked = ", ".join(fields) + ("," if len(fields) == 1 else "")
        # a plain dict of every field in order (what the core gives: a
        # timeStamp, an alarm, a MethodLog) unpacked in one step; anything
        # else checked and read field by field
        lines += [
            f"{pad}{keys} = tuple({data}) if type({data}) is dict else None\n",
            f"{pad}if {keys} == {typed}:\n",
            f"{pad}    {typeid}, {unpacked} = {data}.values()\n",
            f"{pad}    if {typeid} != {spec[1]!r}:\n",
            f"{pad}        return False\n",
        ]
        if spec[1] == STRUCTURE and names:  # no typeid: the plain form fits
            lines += [
                f"{pad}elif {keys} == {plain}:\n",
                f"{pad}    {unpacked} = {data}.values()\n",
            ]
        lines += [
            f"{pad}else:\n",
            f"{pad}    if not isinstance({data}, dict):\n",
            f"{pad}        return False\n",
            f"{pad}    if {data}.get('typeid', {STRUCTURE!r}) != {spec[1]!r}:\n",
            f"{pad}        return False\n",
            f"{pad}    {keys} = tuple({data})\n",
            f"{pad}    if {keys} != {typed} and {keys} != {plain}:\n",
            f"{pad}        {keys} = [k for k in {keys} if k != 'typeid']\n",
        ]
        if subset:
            allowed = self.const(frozenset(names))
            lines.append(f"{pad}        if not set({keys}) <= {allowed}:\n")
        else:
            lines.append(f"{pad}        if tuple({keys}) != {plain}:\n")
        lines.append(f"{pad}            return False\n")
        lines += [
            f"{pad}    {var} = {data}.get({key!r})\n" for var, key in zip(fields, names)
        ]
        prefix = f"{dotted}." if dotted else ""
        for var, (key, sub) in zip(fields, spec[2]):
            if not isinstance(sub, tuple) and _EXACT.get(sub) is not None:
                # a scalar leaf: its type tested first (None is not of it)
                trusted = spec[1] in _COMPARED_FIRST
                lines += self.scalar(sub, prefix + key, var, pad, trusted)
                continue
            lines.append(f"{pad}if {var} is not None:\n")
            lines += self.field(sub, prefix + key, log and key == "value", var, depth)
        if record:
            kept = f"({data}.copy(), str({data}))" if floats else f"{data}.copy()"
            lines.append(f"{pad}last[{dotted!r}] = {kept}\n")
        return lines

    def field(
        self, spec: Spec, dotted: str, subset: bool, data: str, depth: int
    ) -> list[str]:
        pad = "    " * (depth + 1)
        if isinstance(spec, tuple):
            return self.struct(spec, dotted, subset, data, depth + 1)
        sub, where = self.const(spec), repr(dotted)
        exact = _EXACT.get(spec)
        lines = []
        strs = f"type({data}) is list and all(type(x) is str for x in {data})"
        if spec == "as" and self.remember:  # a MethodLog's present
            # equal to what it holds (a list of str that was checked):
            # nothing to check or set; else a list of str as it is
            pad += "    "
            lines += [
                f"{pad[4:]}if {data} != last.get({where}):\n",
                f"{pad}if {strs}:\n",
                f"{pad}    value[{where}] = {data}\n",
                f"{pad}    last[{where}] = list({data})\n",
                f"{pad}elif fits({sub}, {data}):\n",
            ]
        elif spec == "as":
            lines += [
                f"{pad}if {strs}:\n",
                f"{pad}    value[{where}] = {data}\n",
                f"{pad}elif fits({sub}, {data}):\n",
            ]
        elif exact is not None:
            types = self.const(exact)
            lines += [
                f"{pad}if type({data}) in {types}:\n",
                *self.store(pad + "    ", where, data, data, spec in ("f", "d")),
                f"{pad}elif fits({sub}, {data}):\n",
            ]
        else:
            lines.append(f"{pad}if fits({sub}, {data}):\n")
        forget = [f"{pad}    last.pop({where}, None)\n"] if self.remember else []
        return lines + [
            *forget,
            f"{pad}    value[{where}] = _fill({sub}, {data})\n",
            f"{pad}else:\n",
            f"{pad}    return False\n",
        ]

    def scalar(
        self, spec: str, dotted: str, data: str, pad: str, trusted: bool = False
    ) -> list[str]:
        """Lines that set a scalar leaf from ``data`` (maybe None: left as it
        is), or return False if it does not fit; ``trusted`` (a leaf of a
        timeStamp, which the core makes of ints): compared to what it holds
        before its type is checked (equal: nothing to check or set)."""
        sub, where = self.const(spec), repr(dotted)
        types = self.const(_EXACT[spec])
        if self.remember and trusted and spec not in ("f", "d"):
            return [
                f"{pad}if {data} != last.get({where}):\n",
                f"{pad}    if type({data}) in {types}:\n",
                f"{pad}        value[{where}] = {data}\n",
                f"{pad}        last[{where}] = {data}\n",
                f"{pad}    elif {data} is not None:\n",
                f"{pad}        if fits({sub}, {data}):\n",
                f"{pad}            last.pop({where}, None)\n",
                f"{pad}            value[{where}] = _fill({sub}, {data})\n",
                f"{pad}        else:\n",
                f"{pad}            return False\n",
            ]
        if self.remember and spec not in ("f", "d"):
            stored = [
                f"{pad}    if {data} != last.get({where}, MISSING):\n",
                f"{pad}        value[{where}] = {data}\n",
                f"{pad}        last[{where}] = {data}\n",
            ]
        else:
            stored = self.store(pad + "    ", where, data, data, spec in ("f", "d"))
        forget = [f"{pad}        last.pop({where}, None)\n"] if self.remember else []
        return [
            f"{pad}if type({data}) in {types}:\n",
            *stored,
            f"{pad}elif {data} is not None:\n",
            f"{pad}    if fits({sub}, {data}):\n",
            *forget,
            f"{pad}        value[{where}] = _fill({sub}, {data})\n",
            f"{pad}    else:\n",
            f"{pad}        return False\n",
        ]

    def store(
        self, pad: str, where: str, data: str, kept: str, floats: bool = False
    ) -> list[str]:
        """Lines that set leaf ``where`` to ``data`` (with ``last``: unless it
        holds that already; ``kept`` is what ``last`` keeps of it; ``floats``:
        it may be a float, whose zero is always set). ``MISSING`` is unequal
        to anything ``data`` may be (an int, str, bool, float or list)."""
        if not self.remember:
            return [f"{pad}value[{where}] = {data}\n"]
        before = self.var()
        if floats:
            changed = [
                f"{pad}if {data} != {before} or (\n",
                f"{pad}    not {data}\n",
                f"{pad}    and (type({data}) is float or type({before}) is float)\n",
                f"{pad}):\n",
            ]
        else:
            changed = [f"{pad}if {data} != {before}:\n"]
        return [
            f"{pad}{before} = last.get({where}, MISSING)\n",
            *changed,
            f"{pad}    value[{where}] = {data}\n",
            f"{pad}    last[{where}] = {kept}\n",
        ]

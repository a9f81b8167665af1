"""A served channel's puts and method calls (run on the process's loop).

:class:`ChannelRequests` is the put and rpc side of
:class:`malcolm.io.pva.channel._Channel`: a put goes through the block's
model (``process.put``), a call through ``process.post`` with its result
typed by the method's ``returns`` (:mod:`malcolm.io.pva.results`). An
error is the client's, as ``"<ExceptionType>: <message>"``
(:class:`~malcolm.io.pva.ops.OpRunner` answers it).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from p4p import Value
from p4p.server.raw import SharedPV

from malcolm.core import BadValueError

from .convert import _SCALAR_TYPES, STRUCTURE, to_dict
from .results import method_args, result_value

if TYPE_CHECKING:
    from .server import PvaServer

__all__ = ["ChannelRequests"]

# a put's changed set that is a field's value alone; what to_dict and
# _plain_put give back as it is
_VALUE = {"value"}
_SCALARS = frozenset({float, int, str, bool})
# a method channel's changes that leave its returns as they are
_LOGS = frozenset({("took",), ("returned",)})


class ChannelRequests:
    """Puts and calls of a served channel (a mixin of its ``_Channel``:
    the server, path, name and data are the channel's)."""

    server: PvaServer
    name: str
    path: list[str]
    _pending: dict[tuple[str, ...], Any]
    _data: Any
    data: Any
    _block: bool  # the whole block's channel (its path is [mri])
    #: result_value's memo of a method channel's last result (see _rpc)
    _memo: list[Any]

    # ---- operations, on the loop (LoopSharedPV hands them there)
    def put(self, pv: SharedPV, op: Any) -> None:
        self.server._ops.start(op, self._put(op))

    def rpc(self, pv: SharedPV, op: Any) -> None:
        self.server._ops.start(op, self._rpc(op))

    async def _put(self, op: Any) -> None:
        value = op.value()
        mri = self.path[0]
        changed = value.changedSet()
        if changed == _VALUE and len(self.path) == 2:  # a field's value: most
            new = value["value"]
            if type(new) not in _SCALARS:
                new = _plain_put(to_dict(new))
            await self.server.process.put(self.path, new)
            op.done()
            return
        puts: dict[str, Any] = {}  # field -> new value, in the order given
        for dotted in sorted(changed):
            parts = dotted.split(".")
            if len(self.path) == 2:
                field, rest, prefix = self.path[1], parts, ""
            else:
                field, rest, prefix = parts[0], parts[1:], f"{parts[0]}."
            if rest[:1] != ["value"]:
                raise BadValueError(
                    f"{mri}.{'.'.join([field, *rest])}: only a value can be put"
                )
            if field not in puts:
                puts[field] = _plain_put(to_dict(value[f"{prefix}value"]))
        if not puts:
            raise BadValueError(f"{self.name}: a put must set a value")
        for field, new in puts.items():
            await self.server.process.put([mri, field], new)
        op.done()

    async def _rpc(self, op: Any) -> None:
        value = op.value()
        path = self.path
        # (a channel's path is [mri] (a block's: _block) or [mri, field])
        if self._block or not isinstance(value, Value) or value.getID() != STRUCTURE:
            mri, method, args = method_args(path, value, op.pvRequest)
            result = await self.server.process.post([mri, method], args)
            op.done(result_value(result, self._returns(mri, method)))
            return
        # a call on the method's own channel with its arguments as a plain
        # structure (most): method_args's reading of them, in line
        args = value.todict()
        if not _SCALAR_TYPES.issuperset(map(type, args.values())):
            args = method_args(path, value, op.pvRequest)[2]
        result = await self.server.process.post(path, args)
        # its returns as _returns reads them: the pending took and returned
        # leave them as they are
        try:
            data = self._data if self._pending.keys() <= _LOGS else self.data
            returns = data["meta"]["returns"]
        except (KeyError, TypeError):
            returns = self._returns(*path)
        memo = self._memo
        if (
            memo
            and memo[0] is returns
            and type(result) is dict
            and memo[1] == tuple(zip(result, map(type, result.values())))
        ):  # result_value's answer for these keys and types, in line
            op.done(Value(memo[2], result))
        else:
            op.done(result_value(result, returns, memo))

    def _current(self, path: tuple[str, ...]) -> Any:
        """The channel's data, current at ``path``: the changes the fast path
        recorded are applied first only if one of them is at, above or below
        ``path`` (a call's took and returned leave its returns as they are,
        and are not applied for every call)."""
        first = path[0]
        for key in self._pending:
            if key[0] == first:  # (most differ there: a call's took, returned)
                n = min(len(key), len(path))
                if key[:n] == path[:n]:
                    return self.data
        return self._data

    def _returns(self, mri: str, method: str) -> Any:
        """The method's ``returns`` meta: from this channel's copy if it
        holds the method (kept current on the loop), else from the process."""
        try:
            if self.path == [mri, method]:
                return self._current(("meta", "returns"))["meta"]["returns"]
            if self.path == [mri]:
                where = (method, "meta", "returns")
                return self._current(where)[method]["meta"]["returns"]
        except (KeyError, TypeError):
            pass
        return self.server.process.get([mri, method, "meta", "returns"])


def _plain_put(new: Any) -> Any:
    """A put's value as the block takes it (a table's columns without id)."""
    if isinstance(new, dict) and new.get("typeid", STRUCTURE) != STRUCTURE:
        new = {k: v for k, v in new.items() if k != "typeid"}
    return new

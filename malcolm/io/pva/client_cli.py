"""``malcolm get|put|call|ls``: the command-line pvAccess client.

Each command reads the whole block first (channel ``MRI``), so a field or
method that is not there is named with the ones that are, then:

- ``get MRI[.FIELD]`` prints the block (one line per field: an attribute's
  value and any alarm, a method's arguments) or the field;
- ``put MRI.FIELD VALUE`` puts to ``MRI.FIELD`` (VALUE is JSON, or text;
  a string attribute takes the text as it is) and prints the value after;
- ``call MRI.METHOD key=value...`` calls the method (an RPC on
  ``MRI.METHOD``; each value JSON or text, typed by the method's ``takes``)
  and prints what it returned;
- ``ls`` prints the blocks the server offers (the ``blocks`` attribute of
  its block list, :data:`BLOCK_LIST_MRI`).

``--address HOST:PORT`` (default 127.0.0.1:5075) is the server;
``--json`` prints plain data as JSON instead; ``--timeout`` bounds each
command. An error is one line ``malcolm <cmd>: <what and where>: <why>``
and exit status 1; no traceback.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import sys
from collections.abc import Mapping
from typing import Any

__all__ = ["BLOCK_LIST_MRI", "DEFAULT_ADDRESS", "run_command"]

DEFAULT_ADDRESS = "127.0.0.1:5075"
#: the mri of the block whose ``blocks`` attribute lists a server's blocks
BLOCK_LIST_MRI = "localhost"


class CliError(Exception):
    """A failure to report as one line."""


def run_command(name: str, args: argparse.Namespace) -> int:
    """Run ``malcolm NAME`` (get, put, call or ls) with its parsed ``args``
    (the parsers are :func:`malcolm.cli_pva.add_parsers`); the exit status."""
    commands = {"get": _get, "put": _put, "call": _call, "ls": _ls}
    return _run(name, commands[name], args)


def _run(name: str, command: Any, args: argparse.Namespace) -> int:
    try:
        from malcolm.core import MalcolmError

        from .client_backend import PvaBackend
        from .client_channel import parse_address

        parse_address(args.address)
    except ValueError as e:
        print(f"malcolm {name}: {e}", file=sys.stderr)
        return 1

    async def main() -> str:
        quiet_p4p()
        backend = PvaBackend(args.address)
        try:
            return await command(backend, args)
        finally:
            await backend.close()

    try:
        text = asyncio.run(main())
    except (CliError, MalcolmError, ValueError) as e:
        print(f"malcolm {name}: {e}", file=sys.stderr)
        return 1
    except Exception as e:  # no traceback reaches a user
        print(f"malcolm {name}: {type(e).__name__}: {e}", file=sys.stderr)
        return 1
    if text:
        print(text)
    return 0


def quiet_p4p() -> None:
    """No pvxs log lines on stderr (a refused connection is said as a timeout)."""
    import logging

    from p4p import _lvlmap, _p4p

    _p4p.logger_level_set("pvxs.*", _lvlmap[logging.CRITICAL])


# ---- reading the block
def _split(path: str, what: str | None) -> tuple[str, str | None]:
    mri, dot, field = path.rpartition(".")
    if not dot or not mri or not field.isidentifier():
        if what is not None:
            raise CliError(f"{path!r} is not MRI.{what}")
        return path, None
    return mri, field


async def _within(args: argparse.Namespace, where: str, aw: Any) -> Any:
    from malcolm.core import MalcolmError

    timeout = args.timeout if args.timeout and args.timeout > 0 else None
    try:
        return await asyncio.wait_for(aw, timeout)
    except TimeoutError:
        raise CliError(
            f"{where}: no answer within {args.timeout} s (is a server there,"
            " and does it have that block?)"
        ) from None
    except MalcolmError as e:
        text = str(e)
        if text.startswith(f"{where}: "):
            text = text[len(where) + 2 :]
        from .client_convert import RemoteError

        if not isinstance(e, RemoteError):  # its text names its type already
            text = f"{type(e).__name__}: {text}"
        raise CliError(f"{where}: {text}") from None


async def _block(backend: Any, args: argparse.Namespace, mri: str) -> dict[str, Any]:
    from .convert import to_dict

    value = await _within(args, backend.where(mri), backend.get(mri))
    data = to_dict(value)
    if not isinstance(data, dict) or "meta" not in data:
        raise CliError(f"{backend.where(mri)} is not a block")
    return data


def _field(backend: Any, data: dict[str, Any], mri: str, name: str) -> Any:
    if name == "meta" or name not in data or name == "typeid":
        fields = ", ".join(k for k in data if k not in ("typeid", "meta"))
        raise CliError(
            f"{backend.where(mri)} has no field {name!r} (fields: {fields or 'none'})"
        )
    return data[name]


def _is_method(d: Any) -> bool:
    return isinstance(d, dict) and str(d.get("typeid", "")).startswith(
        "malcolm:core/Method"
    )


# ---- printing
def _text(value: Any) -> str:
    if isinstance(value, str):
        return value
    if isinstance(value, dict) and value.get("typeid") == "malcolm:core/Table:1.0":
        value = {k: v for k, v in value.items() if k != "typeid"}
    return json.dumps(value)


def _field_line(name: str, d: Any) -> str:
    if _is_method(d):
        takes = ((d.get("meta") or {}).get("takes") or {}).get("elements") or {}
        state = "" if (d.get("meta") or {}).get("writeable", True) else "  (not now)"
        return f"{name}({', '.join(takes)}){state}"
    if isinstance(d, dict) and "value" in d:
        line = f"{name} = {_text(d['value'])}"
        alarm = d.get("alarm") or {}
        if alarm.get("severity"):
            severity = ("", "MINOR", "MAJOR", "INVALID", "UNDEFINED")[
                min(int(alarm["severity"]), 4)
            ]
            line += f"  [{severity} {alarm.get('message', '')}]".rstrip()
        return line
    return f"{name} = {_text(d)}"


def _block_text(mri: str, data: dict[str, Any]) -> str:
    meta = data.get("meta") or {}
    head = f"{mri}: {meta.get('description', '')}".rstrip(": ")
    lines = [head]
    lines += [
        "  " + _field_line(k, v) for k, v in data.items() if k not in ("typeid", "meta")
    ]
    return "\n".join(lines)


# ---- values from the command line
def _parse(text: str, meta: Mapping[str, Any] | None) -> Any:
    typeid = str((meta or {}).get("typeid", ""))
    if typeid.endswith(("/StringMeta:1.0", "/ChoiceMeta:1.0")):
        return text
    try:
        return json.loads(text)
    except ValueError:
        return text


# ---- the commands
async def _get(backend: Any, args: argparse.Namespace) -> str:
    mri, name = _split(args.path, None)
    try:
        data = await _block(backend, args, mri)
    except CliError:
        if name is None:
            raise
        # MRI.FIELD may be a block whose mri has a dot in it
        data, mri, name = await _block(backend, args, args.path), args.path, None
    if name is None:
        return json.dumps(data) if args.json else _block_text(mri, data)
    d = _field(backend, data, mri, name)
    if args.json:
        return json.dumps(d)
    return _field_line(f"{mri}.{name}", d)


async def _put(backend: Any, args: argparse.Namespace) -> str:
    from malcolm.core import BadValueError, from_dict
    from malcolm.core.metas import plain

    from .convert import to_dict

    mri, name = _split(args.path, "FIELD")
    assert name is not None
    data = await _block(backend, args, mri)
    d = _field(backend, data, mri, name)
    if _is_method(d):
        raise CliError(f"{backend.where(mri)}.{name} is a method: use malcolm call")
    meta_d = d.get("meta") if isinstance(d, dict) else None
    value = _parse(args.value, meta_d)
    channel = f"{mri}.{name}"
    try:
        meta = from_dict(meta_d, name)
        if not meta.writeable:
            raise CliError(f"{backend.where(channel)} is read-only")
        value = plain(meta.validate(value))
    except BadValueError as e:
        raise CliError(f"{backend.where(channel)}: {e}") from None
    await _within(args, backend.where(channel), backend.put(channel, {"value": value}))
    after = to_dict(await _within(args, backend.where(channel), backend.get(channel)))
    if args.json:
        return json.dumps(after)
    return _field_line(channel, after)


async def _call(backend: Any, args: argparse.Namespace) -> str:
    from malcolm.core import from_dict

    from .client_convert import args_value
    from .convert import to_dict

    mri, name = _split(args.path, "METHOD")
    assert name is not None
    data = await _block(backend, args, mri)
    d = _field(backend, data, mri, name)
    if not _is_method(d):
        raise CliError(f"{backend.where(mri)}.{name} is not a method: use malcolm put")
    method = from_dict(d, name)
    elements = method.meta.takes.elements
    params: dict[str, Any] = {}
    for item in args.args:
        key, eq, text = item.partition("=")
        if not eq or not key:
            raise CliError(f"argument {item!r} is not KEY=VALUE")
        if key not in elements:
            known = ", ".join(elements) or "none"
            raise CliError(
                f"{backend.where(mri)}.{name} takes no argument {key!r}"
                f" (it takes: {known})"
            )
        meta = elements[key].to_dict()
        params[key] = _parse(text, meta)
    channel = f"{mri}.{name}"
    value = args_value(params, method.meta.takes)
    result = await _within(args, backend.where(channel), backend.rpc(channel, value))
    returned = to_dict(result)
    if isinstance(returned, dict):
        returned.pop("typeid", None)
    if args.json:
        return json.dumps(returned)
    if not returned:
        return ""
    if isinstance(returned, dict):
        return "\n".join(f"{k} = {_text(v)}" for k, v in returned.items())
    return _text(returned)


async def _ls(backend: Any, args: argparse.Namespace) -> str:
    try:
        data = await _block(backend, args, BLOCK_LIST_MRI)
    except CliError as e:
        raise CliError(f"{e} (the server publishes no list of its blocks)") from None
    blocks = (data.get("blocks") or {}).get("value")
    if not isinstance(blocks, list):
        raise CliError(f"{backend.where(BLOCK_LIST_MRI)} has no 'blocks' list")
    return json.dumps(blocks) if args.json else "\n".join(blocks)

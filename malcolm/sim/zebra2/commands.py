"""The control-port command language: one line in, one reply out.

A `Session` is one control connection.  `Session.feed_line` takes a line
(without its ``\\n``) and returns the reply lines, or ``None`` while a table
write (any line containing ``<``) is still collecting data lines up to the
empty line that ends it.  Replies follow the recorded server: ``OK``,
``OK =value``, ``ERR text``, or ``!item`` lines closed by ``.``.
"""

from __future__ import annotations

import base64
import logging
import re
import struct
from collections.abc import Callable
from dataclasses import dataclass, field

from .box import Box, ChangeCursor
from .fields import TableField
from .layout import GROUPS
from .values import Zebra2Error, parse_integer

log = logging.getLogger(__name__)

MAX_VALUE = 255
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_NUMBERED = re.compile(r"([A-Za-z_][A-Za-z0-9_]*?)([0-9]*)")
_WORD = re.compile(r"\S+")

Reply = list[str]


def ok_value(value: str | list[str]) -> Reply:
    """A value reply: ``OK =v`` or a ``!`` list."""
    if isinstance(value, list):
        return [f"!{v}" for v in value] + ["."]
    if len(value) > MAX_VALUE:
        raise Zebra2Error("Result too long")
    return [f"OK ={value}"]


@dataclass
class _Entity:
    block: str
    number: str
    field: str | None
    attr: str | None


def parse_entity(text: str) -> _Entity:
    """``B[n][.F[.A]]`` or ``B[n].*``/``B.F.*``; errors as the server's."""
    parts = text.split(".")
    if len(parts) > 3:
        raise Zebra2Error("Unexpected character after input")
    for i, part in enumerate(parts):
        if part == "*" and i == len(parts) - 1 and i > 0:
            continue
        m = _NAME.match(part)
        if not m:
            raise Zebra2Error("No name found")
        if m.end() != len(part):
            raise Zebra2Error("Unexpected character after input")
    m = _NUMBERED.fullmatch(parts[0])
    assert m
    block, number = m.groups()
    return _Entity(
        block,
        number,
        parts[1] if len(parts) > 1 else None,
        parts[2] if len(parts) > 2 else None,
    )


@dataclass
class _TableWrite:
    target: str
    op: str  # "<", "<B", "<<", "<<B", "<<|", "<<|B"
    lines: list[str] = field(default_factory=list)


class Session:
    """One control connection: its `ChangeCursor` and any table write."""

    def __init__(self, box: Box, pcap: object | None = None, who: str = "") -> None:
        self.box = box
        self.pcap = pcap
        self.cursor = ChangeCursor()
        self.table: _TableWrite | None = None
        self.who = who
        #: set by the server: returns the ``*WHO?`` lines
        self.who_lines: Callable[[], list[str]] = lambda: []

    # -- entry point ---------------------------------------------------------
    def feed_line(self, line: str) -> Reply | None:
        """Handle one line; ``None`` while a table write collects data."""
        if self.table is not None:
            if line != "":
                self.table.lines.append(line)
                return None
            table, self.table = self.table, None
            if self.pcap is not None:
                self.pcap.sync()  # type: ignore[attr-defined]
            return self._guard(lambda: self._table_write(table))
        if "<" in line:
            target, _, rest = line.partition("<")
            self.table = _TableWrite(target, "<" + rest)
            return None
        if self.pcap is not None:
            self.pcap.sync()  # type: ignore[attr-defined]
        return self._guard(lambda: self._command(line))

    @staticmethod
    def _guard(action: Callable[[], Reply]) -> Reply:
        try:
            return action()
        except Zebra2Error as e:
            return [f"ERR {e}"]
        except Exception as e:  # a simulator bug: one reply, the box lives on
            log.exception("zebra2 sim: command failed")
            return [f"ERR Internal error: {type(e).__name__}"]

    def _command(self, line: str) -> Reply:
        if line.strip() == "":
            raise Zebra2Error("Unknown command")
        q, e = line.find("?"), line.find("=")
        if q < 0 and e < 0:
            raise Zebra2Error("Unknown command")
        if line.startswith("*"):
            return self._system(line)
        if e < 0 or 0 <= q < e:
            name, rest = line[:q], line[q + 1 :]
            if rest:
                raise Zebra2Error("Unexpected text after command")
            return self._get(parse_entity(name))
        self._put(parse_entity(line[:e]), line[e + 1 :])
        return ["OK"]

    # -- entities ----------------------------------------------------------
    def _get(self, ent: _Entity) -> Reply:
        bdef, inst = self.box.instance(ent.block, ent.number)
        if ent.field is None:
            raise Zebra2Error("Unknown command")
        if ent.field == "*":
            return ok_value(
                [f"{f.name} {f.index} {f.info}" for f in bdef.fields.values()]
            )
        fdef = bdef.fields.get(ent.field)
        if fdef is None:
            raise Zebra2Error("No such field")
        if ent.attr == "*":
            return ok_value(list(fdef.attrs))
        if inst is None:
            raise Zebra2Error("Missing block number")
        state = inst.fields[ent.field]
        if ent.attr is None:
            return ok_value(state.read())
        return ok_value(state.read_attr(ent.attr))

    def _put(self, ent: _Entity, value: str) -> None:
        bdef, inst = self.box.instance(ent.block, ent.number)
        if ent.field is None or ent.field == "*" or ent.attr == "*":
            raise Zebra2Error("Unknown command")
        if ent.field not in bdef.fields:
            raise Zebra2Error("No such field")
        if inst is None:
            raise Zebra2Error("Missing block number")
        state = inst.fields[ent.field]
        if ent.attr is None:
            state.write(value)
        else:
            state.write_attr(ent.attr, value)
        self._after_write()

    def _after_write(self) -> None:
        if self.pcap is not None:
            self.pcap.wiring_changed()  # type: ignore[attr-defined]

    # -- tables ------------------------------------------------------------
    def _table_write(self, table: _TableWrite) -> Reply:
        op = table.op
        if op not in ("<", "<B", "<<", "<<B", "<<|", "<<|B"):
            raise Zebra2Error("Unexpected character after input")
        if table.target.startswith("*"):
            return self._metadata_table(table)
        ent = parse_entity(table.target)
        bdef, inst = self.box.instance(ent.block, ent.number)
        if ent.field is None or ent.attr is not None:
            raise Zebra2Error("Unknown command")
        if ent.field not in bdef.fields:
            raise Zebra2Error("No such field")
        if inst is None:
            raise Zebra2Error("Missing block number")
        state = inst.fields[ent.field]
        if not isinstance(state, TableField):
            raise Zebra2Error("Field is not a table")
        words = _base64_words(table.lines) if op.endswith("B") else _words(table.lines)
        state.write_table(words, stream=op.startswith("<<"), last="|" in op)
        return ["OK"]

    def _metadata_table(self, table: _TableWrite) -> Reply:
        if not table.target.startswith("*METADATA.") or table.op != "<":
            raise Zebra2Error("Unknown command")
        meta = self._meta(table.target[len("*METADATA.") :])
        if not meta.multiline:
            raise Zebra2Error("Not a multi-line field")
        for line in table.lines:
            _check_utf8(line)
        meta.value = list(table.lines)
        self.box.touch(meta.key)
        return ["OK"]

    # -- system commands ---------------------------------------------------
    def _system(self, line: str) -> Reply:
        body = line[1:]
        q, e = body.find("?"), body.find("=")
        is_get = e < 0 or 0 <= q < e
        if body.startswith("ECHO"):
            return self._echo(body, is_get)
        name, rest = (body[:q], body[q + 1 :]) if is_get else (body[:e], body[e + 1 :])
        if is_get and rest:
            raise Zebra2Error("Unexpected text after command")
        head, _, tail = name.partition(".")
        handler = {
            "IDN": self._idn,
            "WHO": self._who,
            "BLOCKS": self._blocks,
            "CLOCK_FREQ": self._clock_freq,
            "DESC": self._desc,
            "ENUMS": self._enums,
            "CHANGES": self._changes,
            "CAPTURE": self._capture,
            "POSITIONS": self._static_list,
            "BITS": self._static_list,
            "METADATA": self._metadata,
            "PCAP": self._pcap,
            "SAVESTATE": self._noop,
            "VERBOSE": self._noop,
        }.get(head)
        if handler is None or (tail and head in ("IDN", "WHO", "BLOCKS")):
            raise Zebra2Error("Unknown command")
        return handler(head, tail, None if is_get else rest)

    def _echo(self, body: str, is_get: bool) -> Reply:
        if not is_get:
            raise Zebra2Error("Command not writeable")
        if not body.startswith("ECHO "):
            raise Zebra2Error("Character ' ' expected")
        if not body.endswith("?"):
            raise Zebra2Error("Unknown command")
        return ok_value(body[len("ECHO ") : -1])

    def _read_only(self, value: str | None) -> None:
        if value is not None:
            raise Zebra2Error("Command not writeable")

    def _idn(self, head: str, tail: str, value: str | None) -> Reply:
        self._read_only(value)
        return ok_value(self.box.layout.idn)

    def _who(self, head: str, tail: str, value: str | None) -> Reply:
        self._read_only(value)
        return ok_value(self.who_lines())

    def _blocks(self, head: str, tail: str, value: str | None) -> Reply:
        self._read_only(value)
        return ok_value(
            [f"{b.name} {b.count}" for b in self.box.layout.blocks.values()]
        )

    def _clock_freq(self, head: str, tail: str, value: str | None) -> Reply:
        self._read_only(value)
        return ok_value("125000000")

    def _noop(self, head: str, tail: str, value: str | None) -> Reply:
        if value is None:
            raise Zebra2Error("Command not readable")
        return ["OK"]

    def _static_list(self, head: str, tail: str, value: str | None) -> Reply:
        self._read_only(value)
        if tail:
            raise Zebra2Error("Unknown command")
        return ok_value(list(self.box.layout.system[f"*{head}?"]["values"]))

    def _desc(self, head: str, tail: str, value: str | None) -> Reply:
        self._read_only(value)
        block, fdef, attr, column = self._describe(tail)
        if fdef is None:
            if block.desc is None:
                raise Zebra2Error("No description set for block")
            return ok_value(block.desc)
        desc = fdef.desc
        if column is not None:
            desc = column.desc
        elif attr is not None:
            desc = fdef.attrs[attr].desc
        if desc is None:
            raise Zebra2Error("No description set for field")
        return ok_value(desc)

    def _enums(self, head: str, tail: str, value: str | None) -> Reply:
        self._read_only(value)
        block, fdef, attr, column = self._describe(tail)
        if fdef is None:
            raise Zebra2Error("No such field")
        if column is not None:
            if column.enums is None:
                raise Zebra2Error("Field is not an enumeration")
            return ok_value(list(column.enums))
        if attr is not None:
            enums = fdef.attrs[attr].enums
            if enums is None:
                raise Zebra2Error("Attribute is not an enumeration")
            return ok_value(list(enums))
        if fdef.enums is None:
            raise Zebra2Error("Field is not an enumeration")
        return ok_value(list(fdef.enums))

    def _describe(self, text: str):  # noqa: ANN202 - internal tuple
        column_name = None
        if "[]." in text:
            text, column_name = text.split("[].", 1)
        ent = parse_entity(text)
        block, _ = self.box.instance(ent.block, ent.number)
        if ent.field is None:
            return block, None, None, None
        fdef = block.fields.get(ent.field)
        if fdef is None:
            raise Zebra2Error("No such field")
        if ent.attr is not None and ent.attr not in fdef.attrs:
            raise Zebra2Error("No such attribute")
        column = None
        if column_name is not None:
            column = next((c for c in fdef.columns if c.name == column_name), None)
            if column is None:
                raise Zebra2Error("No such field")
        return block, fdef, ent.attr, column

    def _changes(self, head: str, tail: str, value: str | None) -> Reply:
        if tail and tail not in GROUPS:
            raise Zebra2Error("Unknown changes selection")
        groups = (tail,) if tail else GROUPS
        if value is None:
            return self.box.changes(self.cursor, groups) + ["."]
        self.box.reset_changes(self.cursor, groups, value)
        return ["OK"]

    def _capture(self, head: str, tail: str, value: str | None) -> Reply:
        system = self.box.layout.system
        if tail in ("OPTIONS", "ENUMS"):
            self._read_only(value)
            return ok_value(list(system[f"*CAPTURE.{tail}?"]["values"]))
        if tail == "*":
            self._read_only(value)
            return ok_value(list(system["*CAPTURE.*?"]["values"]))
        if tail:
            raise Zebra2Error("Unknown command")
        if value is not None:
            if value:
                raise Zebra2Error("Unexpected character after input")
            self.box.clear_capture()
            return ["OK"]
        return ok_value(
            [
                f"{state.key} {state.attrs['CAPTURE']}"
                for state in self.box.capture_fields()
            ]
        )

    def _meta(self, key: str):  # noqa: ANN202
        meta = self.box.metadata.get(key)
        if meta is None:
            raise Zebra2Error(f"Metadata key {key} not found")
        return meta

    def _metadata(self, head: str, tail: str, value: str | None) -> Reply:
        if tail == "*":
            self._read_only(value)
            return ok_value(list(self.box.metadata))
        meta = self._meta(tail)
        if value is None:
            return ok_value(meta.value)
        if meta.constant or meta.multiline:
            raise Zebra2Error("Cannot write to this field")
        _check_utf8(value)
        meta.value = value
        self.box.touch(meta.key)
        return ["OK"]

    def _pcap(self, head: str, tail: str, value: str | None) -> Reply:
        pcap = self.pcap
        if pcap is None:
            raise Zebra2Error("Invalid *PCAP field")
        readers = {
            "STATUS": pcap.status,  # type: ignore[attr-defined]
            "CAPTURED": pcap.captured,  # type: ignore[attr-defined]
            "COMPLETION": pcap.completion,  # type: ignore[attr-defined]
        }
        writers = {
            "ARM": pcap.arm,  # type: ignore[attr-defined]
            "DISARM": pcap.disarm,  # type: ignore[attr-defined]
        }
        if value is None:
            if tail not in readers:
                raise Zebra2Error("Invalid *PCAP field")
            return ok_value(readers[tail]())
        if tail not in writers:
            raise Zebra2Error("Invalid *PCAP field")
        if value:
            raise Zebra2Error("Unexpected character after input")
        writers[tail]()
        return ["OK"]


def _check_utf8(text: str) -> None:
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        raise Zebra2Error("Malformed UTF-8 encoding") from None


def _words(lines: list[str]) -> list[int]:
    words = []
    for line in lines:
        if line.endswith(" ") or "," in line:
            raise Zebra2Error("Number missing")
        for token in _WORD.findall(line):
            words.append(parse_integer(token) % (1 << 32))
    return words


def _base64_words(lines: list[str]) -> list[int]:
    words: list[int] = []
    for line in lines:
        try:
            data = base64.b64decode(line + "=" * (-len(line) % 4), validate=True)
        except ValueError:
            raise Zebra2Error("Invalid data length") from None
        if len(data) % 4:
            raise Zebra2Error("Invalid data length")
        words.extend(struct.unpack(f"<{len(data) // 4}I", data))
    return words

"""The control-port command language: one line in, one reply out.

A `Session` is one control connection.  `Session.feed_line` takes a line
(without its ``\\n``) and returns the reply lines, or ``None`` while a table
write (any line containing ``<``) is still collecting data lines up to the
empty line that ends it.  Replies follow the recorded server: ``OK``,
``OK =value``, ``ERR text``, or ``!item`` lines closed by ``.``.  Lines
starting with ``*`` are answered by `SystemCommands`.
"""

from __future__ import annotations

import base64
import logging
import re
import struct
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from .box import Box, ChangeCursor
from .fields import TableField
from .syntax import Entity, Reply, check_utf8, ok_value, parse_entity
from .system import SystemCommands
from .values import Zebra2Error, parse_integer

if TYPE_CHECKING:
    from .simulation import Simulation

log = logging.getLogger(__name__)

_WORD = re.compile(r"\S+")


@dataclass
class _TableWrite:
    target: str
    op: str  # "<", "<B", "<<", "<<B", "<<|", "<<|B"
    lines: list[str] = field(default_factory=list)


class Session(SystemCommands):
    """One control connection: its `ChangeCursor` and any table write."""

    def __init__(self, box: Box, sim: Simulation | None = None) -> None:
        self.box = box
        self.sim = sim
        self.cursor = ChangeCursor()
        self.table: _TableWrite | None = None
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
            if self.sim is not None:
                self.sim.sync()
            return self._guard(lambda: self._table_write(table))
        if "<" in line:
            target, _, rest = line.partition("<")
            self.table = _TableWrite(target, "<" + rest)
            return None
        if self.sim is not None:
            self.sim.sync()
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
    def _get(self, ent: Entity) -> Reply:
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

    def _put(self, ent: Entity, value: str) -> None:
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
        if self.sim is not None:
            self.sim.wiring_changed()

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
            check_utf8(line)
        meta.value = list(table.lines)
        self.box.touch(meta.key)
        return ["OK"]

    # -- system commands ---------------------------------------------------


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

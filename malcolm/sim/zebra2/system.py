"""System commands (``*IDN?``, ``*CHANGES``, ``*PCAP.ARM=``, ...).

`SystemCommands` is the half of a control `Session` that answers lines
starting with ``*``; it reads the session's box, change cursor and
simulation.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

from .box import Box, ChangeCursor, MetadataKey
from .layout import GROUPS, BlockDef, ColumnDef, FieldDef
from .syntax import Reply, check_utf8, ok_value, parse_entity
from .values import Zebra2Error

if TYPE_CHECKING:
    from .simulation import Simulation


class SystemCommands:
    """Handlers of the ``*`` commands (mixed into `Session`)."""

    box: Box
    cursor: ChangeCursor
    sim: Simulation | None
    who_lines: Callable[[], list[str]]

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

    def _describe(
        self, text: str
    ) -> tuple[BlockDef, FieldDef | None, str | None, ColumnDef | None]:
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

    def _meta(self, key: str) -> MetadataKey:
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
        check_utf8(value)
        meta.value = value
        self.box.touch(meta.key)
        return ["OK"]

    def _pcap(self, head: str, tail: str, value: str | None) -> Reply:
        sim = self.sim
        if sim is None:
            raise Zebra2Error("Invalid *PCAP field")
        readers = {
            "STATUS": sim.status,
            "CAPTURED": sim.captured,
            "COMPLETION": sim.completion,
        }
        writers = {"ARM": sim.arm, "DISARM": sim.disarm}
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

"""What a box says about itself: blocks, fields, attributes, table columns.

:func:`introspect` asks a box's control port (``*BLOCKS?``, ``*DESC``,
``B.*?``, ``B.F.*?``, ``*ENUMS``, the attributes that fix a field's meta,
``B1.TABLE.FIELDS?``, the table columns' labels) in five pipelined rounds and returns a
:class:`BoxLayout`. Field values are not read here: the first ``*CHANGES?``
of a connection reports every value.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from .control import ControlClient, Reply

__all__ = [
    "BlockLayout",
    "BoxLayout",
    "FieldLayout",
    "TableColumn",
    "instance_names",
    "introspect",
]

#: field types whose ``*ENUMS.B.F?`` gives the labels a value may take
_ENUM_TYPES = {"bit_mux", "pos_mux"}
#: attributes whose enumeration labels are read
_ENUM_ATTRS = {"CAPTURE", "UNITS"}
#: attributes whose value fixes the meta (read once, at introspection)
_FIXED_ATTRS = {"MAX", "MAX_DELAY", "ROW_WORDS", "MAX_LENGTH", "CAPTURE_WORD", "OFFSET"}


@dataclass
class TableColumn:
    """A table column: bits ``high:low`` of a row's words, as a number or an
    enum label (``labels``)."""

    name: str
    high: int
    low: int
    subtype: str
    description: str = ""
    labels: tuple[str, ...] = ()


@dataclass
class FieldLayout:
    """One field of a block type (``PCOMP.START``)."""

    name: str
    index: int
    type: str
    subtype: str = ""
    description: str = ""
    #: enum labels of the value (enum subtype, bit_mux, pos_mux)
    labels: tuple[str, ...] = ()
    #: attribute names (``UNITS``, ``CAPTURE``...), INFO left out
    attributes: tuple[str, ...] = ()
    #: attribute -> labels (``CAPTURE``, ``UNITS``)
    attribute_labels: dict[str, tuple[str, ...]] = field(default_factory=dict)
    #: attribute -> the value of instance 1 (MAX, ROW_WORDS, ...)
    fixed: dict[str, str] = field(default_factory=dict)
    columns: tuple[TableColumn, ...] = ()

    @property
    def kind(self) -> str:
        """``type`` or, for param/read/write, the subtype (``uint``...)."""
        if self.type in ("param", "read", "write"):
            return self.subtype or "uint"
        if self.type == "time":
            return "time"
        return self.type


@dataclass
class BlockLayout:
    """A block type and how many instances the box has."""

    name: str
    count: int
    description: str = ""
    fields: list[FieldLayout] = field(default_factory=list)

    @property
    def instances(self) -> list[str]:
        return instance_names(self.name, self.count)


@dataclass
class BoxLayout:
    """Every block type of a box, in ``*BLOCKS?`` order."""

    idn: str
    blocks: list[BlockLayout]

    def block(self, name: str) -> BlockLayout:
        for b in self.blocks:
            if b.name == name:
                return b
        raise KeyError(name)


def instance_names(block: str, count: int) -> list[str]:
    """``PCOMP1``, ``PCOMP2``; a single-instance block has no number
    (``SEQ``), as in ``*CHANGES`` and the mux labels."""
    if count == 1:
        return [block]
    return [f"{block}{i}" for i in range(1, count + 1)]


def _lines(reply: Reply | Exception) -> list[str]:
    if isinstance(reply, Reply) and reply.lines is not None:
        return list(reply.lines)
    return []


def _value(reply: Reply | Exception) -> str:
    if isinstance(reply, Reply) and reply.value is not None:
        return reply.value
    return ""


def _raise(reply: Reply | Exception) -> Reply:
    if isinstance(reply, Exception):
        raise reply
    return reply


def _column(text: str) -> TableColumn:
    bits, name, *rest = text.split()
    high, _, low = bits.partition(":")
    return TableColumn(name, int(high), int(low or high), rest[0] if rest else "uint")


async def introspect(client: ControlClient) -> BoxLayout:
    """Read a box's blocks and fields (see the module docstring)."""
    idn, blocks_reply = await client.send_many(["*IDN?", "*BLOCKS?"])
    blocks = []
    for item in _lines(_raise(blocks_reply)):
        name, _, count = item.partition(" ")
        blocks.append(BlockLayout(name, int(count or 1)))
    # round 2: descriptions and field lists
    commands = []
    for b in blocks:
        commands += [f"*DESC.{b.name}?", f"{b.name}.*?"]
    replies = await client.send_many(commands)
    for i, b in enumerate(blocks):
        b.description = _value(replies[2 * i])
        for item in _lines(_raise(replies[2 * i + 1])):
            name, index, ftype, *sub = item.split()
            b.fields.append(FieldLayout(name, int(index), ftype, sub[0] if sub else ""))
        b.fields.sort(key=lambda f: f.index)
    # round 3: field descriptions, attribute lists, labels
    commands, where = [], []
    for b in blocks:
        for f in b.fields:
            commands += [f"*DESC.{b.name}.{f.name}?", f"{b.name}.{f.name}.*?"]
            where += [(f, "desc"), (f, "attrs")]
            if f.type in _ENUM_TYPES or f.subtype == "enum":
                commands.append(f"*ENUMS.{b.name}.{f.name}?")
                where.append((f, "labels"))
    for (f, what), reply in zip(where, await client.send_many(commands)):
        if what == "desc":
            f.description = _value(reply)
        elif what == "attrs":
            f.attributes = tuple(a for a in _lines(reply) if a != "INFO")
        else:
            f.labels = tuple(_lines(reply))
    # round 4: attribute labels, fixed attribute values, table columns
    commands, where2 = [], []
    for b in blocks:
        first = f"{b.name}1" if b.count > 1 else b.name
        for f in b.fields:
            for a in f.attributes:
                if a in _ENUM_ATTRS:
                    commands.append(f"*ENUMS.{b.name}.{f.name}.{a}?")
                    where2.append((f, "labels", a))
                if a in _FIXED_ATTRS:
                    commands.append(f"{first}.{f.name}.{a}?")
                    where2.append((f, "fixed", a))
            if f.type == "table":
                commands.append(f"{first}.{f.name}.FIELDS?")
                where2.append((f, "columns", ""))
    for (f, what, a), reply in zip(where2, await client.send_many(commands)):
        if what == "labels":
            f.attribute_labels[a] = tuple(_lines(reply))
        elif what == "fixed":
            f.fixed[a] = _value(reply)
        else:
            f.columns = tuple(_column(t) for t in _lines(reply))
    # round 5: labels of enum table columns
    commands, where3 = [], []
    for b in blocks:
        for f in b.fields:
            for c in f.columns:
                if c.subtype == "enum":
                    commands.append(f"*ENUMS.{b.name}.{f.name}[].{c.name}?")
                    where3.append(c)
                commands.append(f"*DESC.{b.name}.{f.name}[].{c.name}?")
                where3.append(c)
    for c, reply in zip(where3, await client.send_many(commands) if commands else []):
        if isinstance(reply, Reply) and reply.lines is not None:
            c.labels = tuple(reply.lines)
        else:
            c.description = _value(reply).strip()
    return BoxLayout(_value(idn), blocks)

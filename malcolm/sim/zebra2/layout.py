"""The static description of a simulated box, read from a recorded introspection.

The JSON files in ``data/`` are the recorded output of a real
PandABlocks-server (see /work/shared/zebra2/README.md): every block, field,
attribute, description, enumeration and table column, the system lists, and
the first ``*CHANGES`` reply of each group, whose order is the server's
internal field order.  `load_layout` turns one of them into a `Layout`; the
simulator's state starts from the recorded first values.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from functools import cache
from importlib import resources
from typing import Any

LAYOUTS = ("tier1", "tier2")

#: *CHANGES groups, in the order the server lists them in ``*CHANGES?``
GROUPS = ("CONFIG", "BITS", "POSN", "READ", "ATTR", "TABLE", "METADATA")


@dataclass
class AttrDef:
    """One attribute of a field (``B.F.ATTR``)."""

    name: str
    desc: str | None
    enums: list[str] | None
    initial: dict[str, Any]


@dataclass
class ColumnDef:
    """One column of a table field (``B.F[].COL``)."""

    name: str
    bits: str
    subtype: str
    desc: str | None
    enums: list[str] | None


@dataclass
class FieldDef:
    """One field of a block type, with its recorded attributes and first value."""

    name: str
    index: int
    type: str
    subtype: str | None
    desc: str | None
    enums: list[str] | None
    initial: dict[str, Any]
    attrs: dict[str, AttrDef]
    columns: list[ColumnDef] = field(default_factory=list)

    @property
    def info(self) -> str:
        """The ``INFO`` attribute: the type string of ``B.*?``."""
        return f"{self.type} {self.subtype}" if self.subtype else self.type


@dataclass
class BlockDef:
    """One block type: its instance count and fields in ``B.*?`` order."""

    name: str
    count: int
    desc: str | None
    fields: dict[str, FieldDef]

    def instance_name(self, n: int) -> str:
        """The name in ``*CHANGES`` and mux lists: no number if single."""
        return self.name if self.count == 1 else f"{self.name}{n}"


@dataclass
class Layout:
    """Everything static about one recorded box."""

    name: str
    idn: str
    blocks: dict[str, BlockDef]
    system: dict[str, Any]
    metadata: dict[str, dict[str, Any]]
    #: reportable keys ("PCOMP1.START", "PCOMP1.ENABLE.DELAY", "SEQ.TABLE<",
    #: "*METADATA.YAML<") in the server's order, with their group
    changes: list[tuple[str, str]]
    #: whether tables accept ``<<`` streaming writes
    streaming_tables: bool
    #: whether PCAP produces the dumb simulator's synthetic words (tier 1)
    synthetic_capture: bool


def _value(reply: dict[str, Any]) -> str | None:
    return reply.get("value")


def _values(reply: dict[str, Any]) -> list[str] | None:
    return reply.get("values")


def _change_key(line: str) -> str:
    body = line[1:]
    if body.endswith(" (error)"):
        return body[: -len(" (error)")]
    if body.endswith("<"):
        return body
    return body.split("=", 1)[0]


@cache
def _load_json(name: str) -> dict[str, Any]:
    if name not in LAYOUTS:
        raise ValueError(f"unknown layout {name!r}: expected one of {LAYOUTS}")
    text = (
        resources.files("malcolm.sim.zebra2")
        .joinpath("data", f"introspection-{name}.json")
        .read_text(encoding="utf-8")
    )
    return json.loads(text)


def load_layout(name: str = "tier2") -> Layout:
    """Build the `Layout` of a recorded box (``tier1`` or ``tier2``)."""
    data = _load_json(name)
    raw = data["raw"]
    blocks: dict[str, BlockDef] = {}
    for entry in data["blocks"]:
        bname, count = entry["name"], entry["count"]
        details = data["block_details"][bname]
        by_name: dict[str, FieldDef] = {}
        for f in details["fields"]:
            attrs = {
                aname: AttrDef(
                    aname, _value(a["desc"]), _values(a["enums"]), a["value_instance1"]
                )
                for aname, a in f["attributes"].items()
            }
            columns = [
                ColumnDef(
                    c["name"],
                    c["bits"],
                    c["subtype"],
                    _value(c["desc"]),
                    _values(c.get("enums", {})),
                )
                for c in f.get("table_columns") or []
            ]
            by_name[f["name"]] = FieldDef(
                f["name"],
                f["index"],
                f["type"],
                f["subtype"],
                _value(f["desc"]),
                _values(f["enums"]),
                f["value_instance1"],
                attrs,
                columns,
            )
        # the B.*? order (fixed, unsorted) as recorded
        listing = raw.get(f"{bname}.*?", [])
        order = [line[1:].split(" ", 1)[0] for line in listing if line != "."]
        fields = {n: by_name[n] for n in order if n in by_name}
        fields.update({n: f for n, f in by_name.items() if n not in fields})
        blocks[bname] = BlockDef(bname, count, _value(details["desc"]), fields)
    system = data["system_commands"]
    metadata: dict[str, dict[str, Any]] = {}
    for key in _values(system["*METADATA.*?"]) or []:
        metadata[key] = system[f"*METADATA.{key}?"]
    group_of: dict[str, str] = {}
    for group in GROUPS:
        for line in data["changes_initial"][f"*CHANGES.{group}?"]:
            if line != ".":
                group_of[_change_key(line)] = group
    changes = [
        (key, group_of[key])
        for key in (_change_key(line) for line in data["changes_initial"]["*CHANGES?"])
        if key != "." and key in group_of
    ]
    return Layout(
        name=name,
        idn=data["idn"],
        blocks=blocks,
        system=system,
        metadata=metadata,
        changes=changes,
        streaming_tables=name == "tier2",
        synthetic_capture=name == "tier1",
    )

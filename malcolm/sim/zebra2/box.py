"""The whole simulated box: block instances, metadata and change tracking.

Every reportable key (field, attribute, table marker, metadata key) carries
the sequence number of its last write; a `ChangeCursor` (one per control
connection) remembers, per group, the number it last reported up to.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from .fields import FieldState, make_field
from .layout import GROUPS, BlockDef, Layout
from .values import Zebra2Error

#: the changes cursor value that means "report everything"
EVERYTHING = -1


@dataclass
class ChangeCursor:
    """Per-connection, per-group point up to which changes were reported."""

    seen: dict[str, int] = field(default_factory=lambda: dict.fromkeys(GROUPS, -1))


@dataclass
class Instance:
    """One block instance (``PCOMP1``) and its fields."""

    block: BlockDef
    number: int
    name: str
    fields: dict[str, FieldState]


class MetadataKey:
    """A ``*METADATA`` key: constant, single-line string or multi-line."""

    def __init__(self, name: str, initial: dict) -> None:
        self.name = name
        self.multiline = "values" in initial
        self.value: str | list[str] = initial.get("values", initial.get("value", ""))
        # keys given a value by the configuration are constants
        self.constant = not self.multiline and self.value != ""

    @property
    def key(self) -> str:
        return f"*METADATA.{self.name}" + ("<" if self.multiline else "")


class Box:
    """The state of a simulated box built from a `Layout`."""

    def __init__(self, layout: Layout) -> None:
        self.layout = layout
        self.seq = 0
        self.stamps: dict[str, int] = {}
        self.instances: dict[str, list[Instance]] = {}
        self.by_key: dict[str, tuple[FieldState | MetadataKey, str | None]] = {}
        for bdef in layout.blocks.values():
            insts = []
            for n in range(1, bdef.count + 1):
                iname = bdef.instance_name(n)
                fields = {
                    fname: make_field(
                        f"{iname}.{fname}", fdef, self.touch, layout.streaming_tables
                    )
                    for fname, fdef in bdef.fields.items()
                }
                insts.append(Instance(bdef, n, iname, fields))
                for state in fields.values():
                    self.by_key[state.key] = (state, None)
                    self.by_key[state.key + "<"] = (state, None)
                    for aname in state.fdef.attrs:
                        self.by_key[f"{state.key}.{aname}"] = (state, aname)
            self.instances[bdef.name] = insts
        self.metadata = {k: MetadataKey(k, v) for k, v in layout.metadata.items()}
        for meta in self.metadata.values():
            self.by_key[meta.key] = (meta, None)
        self._place_bits()
        self.order = {key: i for i, (key, _) in enumerate(layout.changes)}
        self.group_keys: dict[str, list[str]] = {g: [] for g in GROUPS}
        for key, group in layout.changes:
            self.group_keys[group].append(key)
        self.group_of = dict(layout.changes)

    def _place_bits(self) -> None:
        """Each bit_out's CAPTURE_WORD and OFFSET from the PCAP.BITSn lists."""
        for insts in self.instances.values():
            for inst in insts:
                for state in inst.fields.values():
                    if state.fdef.type == "ext_out" and state.fdef.subtype == "bits":
                        names = state.fdef.attrs["BITS"].initial.get("values", [])
                        for offset, bit in enumerate(names):
                            target = self.by_key.get(bit)
                            if bit and target:
                                bit_state = target[0]
                                assert isinstance(bit_state, FieldState)
                                bit_state.attrs["CAPTURE_WORD"] = state.key
                                bit_state.attrs["OFFSET"] = str(offset)

    # -- lookup ------------------------------------------------------------
    def instance(self, block: str, number: str) -> tuple[BlockDef, Instance | None]:
        """The block and instance named; no instance if the number is omitted."""
        bdef = self.layout.blocks.get(block)
        if bdef is None:
            raise Zebra2Error("No such block")
        if number == "":
            return bdef, self.instances[block][0] if bdef.count == 1 else None
        n = int(number)
        if not 1 <= n <= bdef.count:
            raise Zebra2Error("Invalid block number")
        return bdef, self.instances[block][n - 1]

    def field(self, key: str) -> FieldState:
        """The field state of ``PCOMP1.START`` (``SEQ.TABLE``: no number)."""
        state = self.by_key[key][0]
        assert isinstance(state, FieldState)
        return state

    # -- changes -----------------------------------------------------------
    def touch(self, key: str) -> None:
        """Record a write of ``key`` (unreportable keys are ignored)."""
        if key in self.group_of:
            self.seq += 1
            self.stamps[key] = self.seq

    def report_line(self, key: str) -> str:
        """The ``*CHANGES`` line of a key with its current value."""
        target, attr = self.by_key[key]
        if key.endswith("<"):
            return f"!{key}"
        try:
            if isinstance(target, MetadataKey):
                value = target.value
            elif attr is None:
                value = target.read()
            else:
                value = target.read_attr(attr)
        except Zebra2Error:
            return f"!{key} (error)"
        assert isinstance(value, str)
        return f"!{key}={value}"

    def changes(self, cursor: ChangeCursor, groups: tuple[str, ...]) -> list[str]:
        """Report (and consume) what changed in ``groups`` for one cursor."""
        keys: list[str] = []
        for group in groups:
            seen = cursor.seen[group]
            if seen == EVERYTHING:
                keys.extend(self.group_keys[group])
            else:
                keys.extend(
                    k for k in self.group_keys[group] if self.stamps.get(k, 0) > seen
                )
            cursor.seen[group] = self.seq
        keys.sort(key=self.order.__getitem__)
        return [self.report_line(k) for k in keys]

    def reset_changes(
        self, cursor: ChangeCursor, groups: tuple[str, ...], option: str
    ) -> None:
        """``*CHANGES=``/``=E`` (discard) or ``=S`` (report all next time)."""
        if option not in ("", "E", "S"):
            raise Zebra2Error("Invalid reset option")
        for group in groups:
            cursor.seen[group] = EVERYTHING if option == "S" else self.seq

    # -- capture -----------------------------------------------------------
    def capture_fields(self) -> list[FieldState]:
        """Fields whose CAPTURE is set, in ``*CAPTURE.*?`` order."""
        return [s for s in self.capturable() if s.attrs.get("CAPTURE", "No") != "No"]

    def capturable(self) -> list[FieldState]:
        """Every field with a CAPTURE attribute, in ``*CAPTURE.*?`` order."""
        names = self.layout.system["*CAPTURE.*?"]["values"]
        return [self.field(name) for name in names]

    def clear_capture(self) -> None:
        """``*CAPTURE=``: every CAPTURE back to ``No`` (changed ones reported)."""
        for state in self.capture_fields():
            state.attrs["CAPTURE"] = "No"
            self.touch(f"{state.key}.CAPTURE")

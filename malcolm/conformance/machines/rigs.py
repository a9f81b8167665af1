"""What the Editor machine drives: a manager, its children's writeable
attributes, and the designs it starts with.

A :class:`Rig` builds a fresh Process per example (``build``) and describes
the children's fields: their metas (from which values are drawn), their
``fixed.<Type>`` kinds and the order a save writes them. Two kinds:

- :class:`ProcessRig`: every block a process file lists; the designs are a
  copy of those saved for the manager (``--malcolm-designs``);
- a rig of soft children a test makes itself (tests/property).
"""

from __future__ import annotations

import math
import shutil
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hypothesis import strategies as st

from malcolm.core import (
    Attribute,
    BooleanArrayMeta,
    BooleanMeta,
    ChoiceMeta,
    NumberArrayMeta,
    NumberMeta,
    Process,
    StringArrayMeta,
    StringMeta,
    TableMeta,
)
from malcolm.parts.design import Design


@dataclass
class Spec:
    """What a design says, in the machine's own terms."""

    exports: list[tuple[str, str, str]] = field(default_factory=list)
    followers: list[tuple[str, str]] = field(default_factory=list)
    fixed: dict[str, Any] = field(default_factory=dict)
    #: child -> (x, y, visible); a design may name only some children
    layout: dict[str, tuple[float, float, bool]] = field(default_factory=dict)
    model: str = ""


@dataclass(frozen=True)
class Field:
    """A writeable child attribute a design may export, follow or fix."""

    dotted: str  # CHILD.FIELD
    mri: str
    name: str
    meta: Any
    kind: str  # its fixed.<Type>

    def values(self) -> st.SearchStrategy[Any]:
        """Values a client might write (the child may refuse some)."""
        return values_of(self.meta)

    def validate(self, value: Any) -> Any:
        return self.meta.validate(value)


_INT_RANGES = {
    "int8": 8,
    "int16": 16,
    "int32": 32,
    "int64": 64,
    "uint8": 8,
    "uint16": 16,
    "uint32": 32,
    "uint64": 64,
}


def _scalars(dtype: str) -> st.SearchStrategy[Any]:
    if dtype.startswith("float"):
        return st.one_of(
            st.sampled_from([0.0, 1.5, -2.0, 5.0]),
            st.integers(-(10**6), 10**6).map(float),
            st.floats(),  # NaN and infinities too
        )
    bits = _INT_RANGES.get(dtype, 32)
    if dtype.startswith("uint"):
        low, high = 0, 2**bits - 1
    else:
        low, high = -(2 ** (bits - 1)), 2 ** (bits - 1) - 1
    special = [v for v in (0, 1, 32, -7) if low <= v <= high]
    return st.one_of(st.sampled_from(special), st.integers(low, high))


def values_of(meta: Any) -> st.SearchStrategy[Any]:
    """Values of ``meta`` (an empty strategy if the machine cannot make any)."""
    if isinstance(meta, BooleanMeta):
        return st.booleans()
    if isinstance(meta, ChoiceMeta):
        return st.sampled_from(list(meta.choices)) if meta.choices else st.nothing()
    if isinstance(meta, NumberMeta):
        return _scalars(meta.dtype)
    if isinstance(meta, StringMeta):
        return st.one_of(st.sampled_from(["", "x", "yes", "1"]), st.text(max_size=12))
    if isinstance(meta, TableMeta):
        columns = {c: _element(m) for c, m in meta.elements.items()}
        if any(s.is_empty for s in columns.values()):
            return st.nothing()
        rows = st.lists(st.fixed_dictionaries(columns), max_size=3)
        return rows.map(lambda rs: meta.validate(rs) if rs else empty_table(meta))
    return st.nothing()


def _element(meta: Any) -> st.SearchStrategy[Any]:
    if isinstance(meta, NumberArrayMeta):
        return _scalars(meta.dtype)
    if isinstance(meta, StringArrayMeta):
        return st.text(max_size=6)
    if isinstance(meta, BooleanArrayMeta):
        return st.booleans()
    return st.nothing()


def empty_table(meta: TableMeta) -> dict[str, tuple[Any, ...]]:
    return {c: () for c in meta.elements}


def same(a: Any, b: Any) -> bool:
    """The machine's own equality: lists and tuples alike, NaN equal to NaN."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if isinstance(a, list | tuple) and isinstance(b, list | tuple):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    if isinstance(a, bool) or isinstance(b, bool):
        return type(a) is type(b) and a == b
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a):
        return math.isnan(b)
    if hasattr(a, "item"):
        a = a.item()
    if hasattr(b, "item"):
        b = b.item()
    if isinstance(a, int | float) and isinstance(b, int | float):
        return type(a) is type(b) and a == b
    return type(a) is type(b) and a == b


class Rig:
    """A manager and its children, built afresh for each example."""

    mri: str = ""

    def build(self, designs_dir: Path) -> tuple[Process, Any]:
        """A Process (not started) with the manager (returned) and children;
        the manager keeps its designs in ``designs_dir``."""
        raise NotImplementedError

    def seed_designs(self, designs_dir: Path) -> None:
        """Put the designs the manager starts with into ``designs_dir``."""

    def fields(self, process: Process, manager: Any) -> dict[str, Field]:
        """The writeable, savable child attributes, in the order save writes."""
        from malcolm.editor.plan import fixed_kind

        found: dict[str, Field] = {}
        for child, mri in manager.children.items():
            block = process.get_block(mri)
            for name, attr in block.attributes.items():
                kind = fixed_kind(attr)
                if attr.meta.writeable and kind is not None:
                    dotted = f"{child}.{name}"
                    found[dotted] = Field(dotted, mri, name, attr.meta, kind)
        return found


def spec_of(design: Design, fields: dict[str, Field], children: Sequence[str]) -> Spec:
    """A loaded design in the machine's terms (a child its palette leaves
    out is where a new manager has it)."""
    from malcolm.parts.design import ExportPart, FollowerPart

    layout = {c: (0.0, 0.0, True) for c in children}
    for p in design.palette:
        layout[p.name] = (float(p.xcoord), float(p.ycoord), p.visible)
    return Spec(
        exports=[(r.name, r.source, r.description) for r in design.of(ExportPart)],
        followers=[(r.name, r.source) for r in design.of(FollowerPart)],
        fixed={r.name: fields[r.name].validate(r.value) for r in design.fixed},
        layout=layout,
        model=design.model or "",
    )


class ProcessRig(Rig):
    """One manager of a process file, with a copy of its saved designs."""

    def __init__(
        self,
        process_file: Path,
        mri: str,
        designs_from: Path,
        search_path: Sequence[str] = (),
    ) -> None:
        self.file = process_file
        self.mri = mri
        self.designs_from = designs_from
        self.search_path = tuple(search_path)

    def build(self, designs_dir: Path) -> tuple[Process, Any]:
        from malcolm.config.build import build_process

        process = Process(self.file.stem, designs_dir=str(designs_dir))
        build_process(self.file, self.search_path, process=process)
        manager = process.get_controller(self.mri)
        manager.designs_dir = str(designs_dir)
        return process, manager

    def seed_designs(self, designs_dir: Path) -> None:
        from malcolm.editor.store import DesignStore

        source = DesignStore(self.mri, self.designs_from).dir
        target = DesignStore(self.mri, designs_dir).dir
        if source.is_dir():
            shutil.copytree(source, target, dirs_exist_ok=True)


def child_value(process: Process, f: Field) -> Any:
    attr = process.get_block(f.mri)[f.name]
    assert isinstance(attr, Attribute)
    return attr.value

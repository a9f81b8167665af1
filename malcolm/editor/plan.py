"""A manager's design as parts: records into table parts, and back.

- ``build_parts``: make (not add) the export, follower and fixed parts of
  a list of design records, raising one BadValueError naming every problem.
- ``check_design``: every problem of a loaded design for a manager (its
  palette and its parts), before anything changes.
- ``design_records``: what ``save`` writes, from the manager's tables and
  its children's writeable attributes.
- ``fixed_kind``: the ``fixed.<Type>`` record a child attribute saves as.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

from malcolm.core import (
    Attribute,
    BadValueError,
    BooleanMeta,
    ChoiceMeta,
    NumberMeta,
    StringMeta,
    TableMeta,
)
from malcolm.editor import tables
from malcolm.editor.runtime import (
    EditorPart,
    ExportRuntime,
    FixedRuntime,
    FollowerRuntime,
    RunnableExportRuntime,
    takes_configure_args,
    writeable_attribute,
)
from malcolm.parts.design import (
    DESIGN_KINDS,
    Design,
    ExportPart,
    FollowerPart,
    ModelPart,
    PalettePart,
)

if TYPE_CHECKING:
    from malcolm.controllers.manager import ManagerController

#: the ``fixed.<Type>`` kinds of a saved design and their records
FIXED_KINDS = {k: c for k, c in DESIGN_KINDS.items() if k.startswith("fixed.")}


def default_designs_dir() -> Path:
    """``$MALCOLM_DESIGNS_DIR``, else ``designs/`` in the working directory."""
    return Path(os.environ.get("MALCOLM_DESIGNS_DIR") or Path.cwd() / "designs")


def records_from_tables(
    manager: ManagerController,
    exports: list[dict[str, Any]] | None = None,
    followers: list[dict[str, Any]] | None = None,
) -> list[Any]:
    """Export and follower records of the manager's tables (or of given rows)."""
    ex = exports if exports is not None else tables.rows(manager.exports.value)
    fo = followers if followers is not None else tables.rows(manager.followers.value)
    return [
        *(ExportPart(r["name"], r["source"], r.get("description", "")) for r in ex),
        *(FollowerPart(r["name"], r["source"]) for r in fo),
    ]


def fixed_text(value: Any, kind: str) -> str:
    """A fixed row's value as the ``fixed`` table shows it: JSON text."""
    return json.dumps(plain_value(value, kind))


def records_from_fixed(
    manager: ManagerController, fixed_rows: list[dict[str, Any]]
) -> list[Any]:
    """``fixed.<Type>`` records of rows of the ``fixed`` table.

    Each row's kind is its child attribute's (``fixed_kind``); its value is
    JSON text. BadValueError naming every row that is not JSON or does not
    name a writeable child attribute; the values are checked by
    ``build_parts``."""
    problems: list[str] = []
    records: list[Any] = []
    for i, row in enumerate(fixed_rows):
        name, text = str(row["name"]), str(row["value"])
        where = f"{manager.mri}.fixed row {i} ({name})"
        try:
            value = json.loads(text)
        except ValueError as e:
            problems.append(f"{where}: value {text!r} is not JSON ({e})")
            continue
        try:
            mri, field = manager.resolve(name)
            attr = writeable_attribute(manager, mri, field, name, "fixed")
        except BadValueError as e:
            problems.append(f"{where}: {str(e).removeprefix(manager.mri + ': ')}")
            continue
        kind = fixed_kind(attr)
        if kind is None:
            problems.append(f"{where}: {type(attr.meta).__name__} cannot be fixed")
            continue
        records.append(FIXED_KINDS[kind](name, value))
    if problems:
        raise BadValueError("\n".join(problems))
    return records


def build_parts(manager: ManagerController, records: list[Any]) -> list[EditorPart]:
    """Make (not add) the parts of a design; BadValueError naming each problem."""
    mri = manager.mri
    problems: list[str] = []
    made: list[EditorPart] = []
    exports: set[str] = set()
    export_cls = (
        RunnableExportRuntime if takes_configure_args(manager) else ExportRuntime
    )
    # fields, and a runnable manager's own configure() arguments
    own = set(manager.block) | set(getattr(manager, "_configure_takes", ()))
    taken = own - {p.field for p in manager._of(ExportRuntime)}
    for r in records:
        try:
            if isinstance(r, ExportPart):
                if not r.name.isidentifier() or r.name in taken | exports:
                    raise BadValueError(
                        f"{mri}: export name {r.name!r} is not a free field name"
                    )
                made.append(export_cls(r.name, r.source, r.description, manager))
                exports.add(r.name)
            elif isinstance(r, FollowerPart):
                # not an export this design drops (the follower would be orphaned)
                if r.source not in exports and r.source not in taken:
                    raise BadValueError(
                        f"{mri}: follower {r.name} follows {r.source!r},"
                        " which is not a field of the manager"
                    )
                source = next(
                    (p for p in made
                     if isinstance(p, ExportRuntime) and p.field == r.source),
                    None,
                )  # fmt: skip
                made.append(
                    FollowerRuntime(
                        r.name,
                        r.source,
                        manager,
                        None if source is None else source.child().meta,
                    )
                )
            elif type(r) in FIXED_KINDS.values():
                kind = next(k for k, c in FIXED_KINDS.items() if c is type(r))
                made.append(FixedRuntime(r.name, r.value, kind, manager))
        except BadValueError as e:
            problems.append(str(e))
    names = [p.name for p in made]
    for twice in sorted({n for n in names if names.count(n) > 1}):
        kind, _, target = twice.partition(":")
        problems.append(f"{mri}: {target} has two {kind} rows")
    moving = {p.source for p in made if isinstance(p, ExportRuntime)} | {
        p.target for p in made if isinstance(p, FollowerRuntime)
    }
    for p in made:
        if isinstance(p, FixedRuntime) and p.target in moving:
            problems.append(
                f"{mri}: {p.target} is fixed, and also exported or followed"
            )
    exported = {p.source for p in made if isinstance(p, ExportRuntime)}
    for p in made:
        if isinstance(p, FollowerRuntime) and p.target in exported:
            # a write through the export would be drift of the follower
            problems.append(f"{mri}: {p.target} is exported, and followed")
    if problems:
        raise BadValueError("\n".join(problems))
    return made


def check_design(manager: ManagerController, design: Design) -> list[EditorPart]:
    """Every problem of a design for this manager, before anything changes."""
    problems = []
    children = manager.children
    for record, (file, line) in zip(design.records, design.lines):
        if isinstance(record, PalettePart) and record.name not in children:
            known = ", ".join(children) or "none"
            problems.append(
                f"{file}:{line}: palette names child {record.name!r}, which"
                f" {manager.mri} does not have (children: {known})"
            )
    try:
        parts = build_parts(manager, design.records)
    except BadValueError as e:
        problems.extend(f"{design.path}: {p}" for p in str(e).splitlines())
        parts = []
    if problems:
        raise BadValueError("\n".join(problems))
    return parts


def design_records(manager: ManagerController) -> list[Any]:
    """What ``save`` writes: model, palette, exports, followers, fixed."""
    records: list[Any] = []
    if manager.model_value:
        records.append(ModelPart(manager.model_value))
    for row in tables.rows(manager.layout.value):
        records.append(
            PalettePart(row["name"], round(row["x"]), round(row["y"]), row["visible"])
        )
    records.extend(records_from_tables(manager))
    exported = {p.source for p in manager._of(ExportRuntime)}
    followed = {p.target for p in manager._of(FollowerRuntime)}
    assert manager.process is not None
    for name, mri in manager.children.items():
        block = manager.process.get_block(mri)
        for field, attr in block.attributes.items():
            dotted = f"{name}.{field}"
            if not attr.meta.writeable or dotted in exported | followed:
                continue
            kind = fixed_kind(attr)
            if kind is not None:
                records.append(FIXED_KINDS[kind](dotted, plain_value(attr.value, kind)))
    return records


def fixed_kind(attr: Attribute) -> str | None:
    """The ``fixed.<Type>`` a child attribute saves as (None: not savable)."""
    meta = attr.meta
    if isinstance(meta, TableMeta):
        return "fixed.Table"
    if isinstance(meta, ChoiceMeta):
        return "fixed.Enum"
    if isinstance(meta, BooleanMeta):
        return "fixed.Bool"
    if isinstance(meta, StringMeta):
        return "fixed.String"
    if isinstance(meta, NumberMeta):
        return "fixed.Float" if meta.dtype.startswith("float") else "fixed.Int"
    return None


def plain_value(value: Any, kind: str) -> Any:
    """A child attribute's value as a ``kind`` record holds it (no numpy)."""
    if kind == "fixed.Table":
        columns = list(value)
        n = len(value[columns[0]]) if columns else 0
        return [{c: _scalar(value[c][i]) for c in columns} for i in range(n)]
    return _scalar(value)


def _scalar(v: Any) -> Any:
    return v.item() if hasattr(v, "item") else v

"""Managers built from a process file, and the checks of their designs.

:class:`DesignRig` builds every block a process file lists into one Process
on its own loop, copies each manager's saved designs into a temporary
directory (the checks save designs; the originals are never written) and
starts the process. :func:`design_problems` then checks one design of one
manager, row by row:

- load: every Fixed child attribute holds the design's value and every
  Follower its source's value; the manager is Ready with health OK;
- for each Fixed and Follower row, a write of another value to the child
  attribute by someone else (a put on the child) sends the manager to
  Fault, and ``health`` names the attribute, the expected and the actual
  value; reset then writes the design's value back and returns to Ready;
- save under a new name and load it back: the same again for every row
  the save wrote (a Fixed row for every writeable child attribute that is
  neither exported nor followed).
"""

from __future__ import annotations

import asyncio
import math
import shutil
import tempfile
from collections.abc import Coroutine, Sequence
from pathlib import Path
from typing import Any

from malcolm.core import (
    Attribute,
    BooleanMeta,
    ChoiceMeta,
    NumberMeta,
    Process,
    StringMeta,
    TableMeta,
)
from malcolm.parts.design import Design, FollowerPart

CALL_TIMEOUT = 10.0
SAVED = "conformance-saved"
SETTLE_TURNS = 1000  # loop turns the manager gets to notice a change


class DesignRig:
    """Every block of a process file, its managers' designs in a temporary copy."""

    def __init__(
        self,
        process_file: str | Path,
        designs_base: str | Path,
        search_path: Sequence[str] = (),
    ) -> None:
        from malcolm.config.build import build_process
        from malcolm.controllers.manager import ManagerController
        from malcolm.editor.store import DesignStore

        self.file = Path(process_file)
        self.loop = asyncio.new_event_loop()
        self.tmp = Path(tempfile.mkdtemp(prefix="malcolm-designs-"))
        self.process = Process(self.file.stem, designs_dir=str(self.tmp))
        try:
            build_process(self.file, search_path, process=self.process)
        except BaseException:
            self.loop.close()
            shutil.rmtree(self.tmp, ignore_errors=True)
            raise
        self.managers: list[ManagerController] = []
        #: a copied store directory -> the one it was copied from
        self.origins: dict[Path, Path] = {}
        for mri in self.process.mris:
            ctrl = self.process.get_controller(mri)
            if isinstance(ctrl, ManagerController):
                source = DesignStore(mri, ctrl.designs_dir or designs_base).dir
                target = DesignStore(mri, self.tmp).dir
                if source.is_dir():
                    shutil.copytree(source, target)
                self.origins[target] = source
                ctrl.designs_dir = str(self.tmp)  # saves go to the copy
                self.managers.append(ctrl)
        self.run(self.process.start())

    def run(self, coro: Coroutine[Any, Any, Any], timeout: float = CALL_TIMEOUT) -> Any:
        return self.loop.run_until_complete(asyncio.wait_for(coro, timeout))

    def original(self, file: str | Path) -> str:
        """Where a design file of the copy came from (itself if not a copy)."""
        path = Path(file)
        source = self.origins.get(path.parent)
        return str(source / path.name) if source is not None else str(path)

    def origins_of(self, manager: Any) -> str:
        """Where a manager's designs were copied from (and its templates)."""
        target = manager.store.dir
        places = [str(self.origins.get(target, target))]
        places += [str(d) for d in manager.store.template_dirs]
        return ", ".join(places)

    def design_names(self, manager: Any) -> list[str]:
        return list(manager.store.names())

    def close(self) -> None:
        try:
            self.run(self.process.stop(), 5)
        finally:
            tasks = asyncio.all_tasks(self.loop)
            for task in tasks:
                task.cancel()
            if tasks:
                self.loop.run_until_complete(
                    asyncio.gather(*tasks, return_exceptions=True)
                )
            self.loop.close()
            shutil.rmtree(self.tmp, ignore_errors=True)


def other_value(meta: Any, value: Any) -> Any:
    """A valid value of ``meta`` that differs from ``value`` (None if none)."""
    if isinstance(meta, BooleanMeta):
        return not value
    if isinstance(meta, ChoiceMeta):
        return next((c for c in meta.choices if c != value), None)
    if isinstance(meta, NumberMeta):
        if meta.dtype.startswith("float"):
            if not isinstance(value, int | float) or not math.isfinite(value):
                return 1.5
            return value + 1.5 if abs(value) < 1e15 else 0.0
        return value - 1 if value > 0 else value + 1
    if isinstance(meta, StringMeta):
        return f"{value}x"
    if isinstance(meta, TableMeta):
        rows = _rows(value)
        if rows:
            return _columns(meta, rows[:-1])
        return _columns(meta, [{c: _zero(m) for c, m in meta.elements.items()}])
    return None


def _zero(meta: Any) -> Any:
    dtype = getattr(meta, "dtype", "")
    if dtype.startswith("float"):
        return 0.0
    if dtype:
        return 0
    if isinstance(meta, BooleanMeta):
        return False
    return ""


def _rows(table: Any) -> list[dict[str, Any]]:
    if not isinstance(table, dict) or not table:
        return []
    n = len(next(iter(table.values())))
    return [{c: table[c][i] for c in table} for i in range(n)]


def _columns(meta: TableMeta, rows: list[dict[str, Any]]) -> dict[str, Any]:
    return {c: [r[c] for r in rows] for c in meta.elements}


def mentions(text: str, value: Any) -> bool:
    """Whether ``text`` shows ``value`` (as repr or str)."""
    return repr(value) in text or str(value) in text


class DesignCheck:
    """Checks one design of one manager in a rig; ``problems`` says what failed."""

    def __init__(self, rig: DesignRig, manager: Any, name: str) -> None:
        self.rig = rig
        self.m = manager
        self.name = name
        self.problems: list[str] = []

    # ---- the live side
    def child(self, dotted: str) -> Attribute:
        mri, field = self.m.resolve(dotted)
        attr = self.rig.process.get_block(mri)[field]
        assert isinstance(attr, Attribute)
        return attr

    def settle(self) -> None:
        async def turns() -> None:
            for _ in range(SETTLE_TURNS):
                await asyncio.sleep(0)
                if not self.m.background:
                    return

        self.rig.run(turns())

    def call(self, name: str, **params: Any) -> BaseException | None:
        try:
            self.rig.run(self.rig.process.post([self.m.mri, name], params))
        except Exception as e:
            return e
        finally:
            self.settle()
        return None

    def put(self, mri: str, field: str, value: Any) -> BaseException | None:
        try:
            self.rig.run(self.rig.process.put([mri, field], value))
        except Exception as e:
            return e
        finally:
            self.settle()
        return None

    def role(self) -> str | None:
        return self.m.model.role_of(self.m.current)

    # ---- the checks
    def where(self, design: Design, record: Any) -> str:
        for r, (file, line) in zip(design.records, design.lines):
            if r is record:
                return f"{self.rig.original(file)}:{line}"
        return self.rig.original(design.path)

    def expected(self, design: Design, record: Any) -> Any:
        """What the design says the child attribute of ``record`` holds."""
        if isinstance(record, FollowerPart):
            return self.m.block.attribute(record.source).value
        value = record.value
        return self.child(record.name).meta.validate(value)

    def rows(self, design: Design) -> list[Any]:
        return [*design.fixed, *design.followers]

    def load(self) -> Design | None:
        error = self.put(self.m.mri, "design", self.name)
        if error is not None:
            self.problems.append(f"load of design {self.name!r} failed: {error}")
            return None
        if self.role() != "ready" or self.m.health.value != "OK":
            self.problems.append(
                f"after load of {self.name!r}, {self.m.mri} is {self.m.current}"
                f" (health {self.m.health.value!r}), not Ready and OK"
            )
            return None
        return self.m.store.load(self.name)

    def holds(self, design: Design, record: Any, when: str) -> bool:
        want = self.expected(design, record)
        have = self.child(record.name).value
        if not same(want, have):
            kind = "follows" if isinstance(record, FollowerPart) else "is fixed at"
            self.problems.append(
                f"{self.where(design, record)}: {when}, {record.name} is {have!r},"
                f" but the design says it {kind} {want!r}"
            )
            return False
        return True

    def drift(self, design: Design, record: Any) -> None:
        """Someone else writes the child: Fault naming it; reset restores it."""
        where = self.where(design, record)
        attr = self.child(record.name)
        want = self.expected(design, record)
        other = other_value(attr.meta, want)
        if other is None:
            return
        mri, field = self.m.resolve(record.name)
        error = self.put(mri, field, other)
        if error is not None:
            self.problems.append(
                f"{where}: a put of {other!r} to {record.name}: {error}"
            )
            return
        actual = attr.value
        health = self.m.health.value
        if self.role() != "fault":
            self.problems.append(
                f"{where}: {record.name} was changed by someone else to {actual!r},"
                f" but {self.m.mri} is {self.m.current}, not Fault"
            )
        elif record.name not in health or not (
            mentions(health, want) and mentions(health, actual)
        ):
            self.problems.append(
                f"{where}: health {health!r} must name {record.name}, the"
                f" expected value {want!r} and the actual value {actual!r}"
            )
        error = self.call("reset")
        if error is not None or self.role() != "ready":
            self.problems.append(
                f"{where}: reset after {record.name} drifted left {self.m.mri}"
                f" {self.m.current} (health {self.m.health.value!r}{_err(error)}),"
                " not Ready"
            )
        self.holds(design, record, "after reset")

    def check(self) -> list[str]:
        design = self.load()
        if design is None:
            return self.problems
        for record in self.rows(design):
            self.holds(design, record, f"after load of {self.name!r}")
        for record in self.rows(design):
            if self.problems:
                break
            self.drift(design, record)
        if self.problems:
            return self.problems
        error = self.call("save", design=SAVED)
        if error is not None:
            self.problems.append(f"save of {self.name!r} as {SAVED!r} failed: {error}")
            return self.problems
        self.name = SAVED
        saved = self.load()
        if saved is None:
            return self.problems
        for record in self.rows(saved):
            if self.problems:
                break
            self.drift(saved, record)
        return self.problems


def _err(error: BaseException | None) -> str:
    return "" if error is None else f"; reset raised {error}"


def same(a: Any, b: Any) -> bool:
    """Equality that treats lists and tuples alike, and NaN as NaN."""
    if isinstance(a, list | tuple) and isinstance(b, list | tuple):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a):
        return math.isnan(b)
    return a == b


def design_problems(rig: DesignRig, manager: Any, name: str) -> list[str]:
    """Every problem :class:`DesignCheck` finds in design ``name``."""
    return DesignCheck(rig, manager, name).check()

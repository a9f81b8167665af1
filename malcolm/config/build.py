"""Build running blocks from definitions: make what :mod:`.plan` planned.

:func:`build_block`, :func:`build_process` and :func:`build_definition` plan
the blocks (:mod:`malcolm.config.plan`: which class makes each controller
and part, with which keywords; everything checkable without calling a
factory is checked there), then make them, children and stand-ins first,
and add them all to the process:

- ``controller.X`` gives the controller (a StatefulController if the
  definition has none), called with the section's keys plus ``mri`` and
  ``parts``;
- every other section (``ca.*``, ``parts.*``...) is one part; ``gui.Group``
  makes a :class:`~malcolm.parts.soft.GroupPart`; a ``block.X`` child or
  ``client.X`` section is controlled by the part its ``part:`` names (a
  plain :class:`~malcolm.parts.base.ChildPart` without one).

Parts are added in the order their sections are written. A failing
constructor, a part whose ``setup`` fails, a field added twice: each is a
problem at the ``file:line`` of its section, reported with the plan's
problems, all together. Nothing is added to the process unless the whole
build succeeded.

:func:`check_block` and :func:`check_process` are the same build as a dry
run for ``malcolm check``: only malcolm's own classes are made (a user's
are imported and inspected by the plan, never called), nothing is added.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from malcolm.controllers.base import Controller
from malcolm.core import Process
from malcolm.parts.base import ChildPart, Part
from malcolm.parts.soft import GroupPart

from .definitions import (
    ExpandedBlock,
    PathLike,
    expand,
    find_definition,
    load_definition,
)
from .errors import ConfigError, Problems
from .inspection import hook_functions
from .plan import BlockPlan, Item, Planner, part_kind
from .process_file import expand_process, load_process_file
from .registry import is_builtin
from .remote import make_remote_block

__all__ = [
    "build_block",
    "build_definition",
    "build_process",
    "check_block",
    "check_process",
    "part_kind",
]


def make_everything(factory: Callable[..., Any]) -> bool:
    """The builder's policy for serving: every factory is called."""
    return True


def make_malcolm_own(factory: Callable[..., Any]) -> bool:
    """The policy for checking: only malcolm's own classes are made, so that
    no user code runs beyond importing it."""
    return factory in (GroupPart, ChildPart) or is_builtin(factory)


@dataclass
class _Built:
    controller: Controller
    file: str
    line: int


class _Builder:
    """Makes the blocks of plans and adds them to a process, all or none."""

    def __init__(
        self,
        process: Process,
        problems: Problems,
        make: Callable[[Callable[..., Any]], bool] = make_everything,
    ) -> None:
        self.process = process
        self.problems = problems
        self.make = make
        self.built: list[_Built] = []

    def block(self, plan: BlockPlan) -> Controller | None:
        for before in plan.before:
            self.block(before)
        controller = self.controller(plan.controller)
        parts = [(item, self.part(item)) for item in plan.parts]
        if controller is None:
            return None
        self.add_parts(controller, parts)
        if plan.standin is not None:
            client = plan.standin
            meta = controller.block.meta
            meta.description = meta.description or (
                f"Soft stand-in for {client.definition} (client '{client.name}' "
                f"at {client.file}:{client.line})"
            )
            meta.tags = (*meta.tags, "standin")
        self.built.append(_Built(controller, plan.file, plan.line))
        return controller

    def controller(self, item: Item | None) -> Controller | None:
        if item is None or item.factory is None or not self.make(item.factory):
            return None
        controller = self.call(item)
        if item.factory is make_remote_block:
            return controller  # a block mirrored from another process
        if controller is not None and not isinstance(controller, Controller):
            self.problems.add(
                item.file,
                item.line,
                f"{item.kind} makes {type(controller).__name__}, not a Controller",
            )
            return None
        return controller

    def part(self, item: Item) -> Part | None:
        if item.factory is None or not self.make(item.factory):
            return None
        part = self.call(item)
        if part is not None and not isinstance(part, Part):
            self.problems.add(
                item.file,
                item.line,
                f"{item.kind} makes {type(part).__name__}, not a Part",
            )
            return None
        return part

    def call(self, item: Item) -> Any:
        """``factory(**kwargs)``; a problem at the section's line, else None."""
        assert item.factory is not None
        try:
            return item.factory(**item.kwargs)
        except ConfigError as error:
            self.problems.problems.extend(error.problems)
        except Exception as error:
            self.problems.add(item.file, item.line, f"{item.kind}: {_why(error)}")
        return None

    def add_parts(
        self, controller: Controller, parts: list[tuple[Item, Part | None]]
    ) -> None:
        owners: dict[str, int] = {}
        for item, part in parts:
            if part is None:
                if item.factory is not None and not self.make(item.factory):
                    self.check_unmade(controller, item)
                continue
            if part.name in controller.parts:
                self.problems.add(
                    item.file,
                    item.line,
                    f"{item.kind}: {controller.mri} already has a part called "
                    f"'{part.name}' (line {owners.get(part.name, '?')})",
                )
                continue
            before = {name: controller.block[name] for name in controller.block}
            try:
                controller.add_part(part)
            except Exception as error:
                self.problems.add(item.file, item.line, f"{item.kind}: {_why(error)}")
                continue
            owners[part.name] = item.line
            for name, old in before.items():
                # configure()/validate() are remade when a part adds arguments
                remade = name in controller.model.methods
                if controller.block[name] is not old and not remade:
                    self.problems.add(
                        item.file,
                        item.line,
                        f"{item.kind}: '{name}' is already a field of "
                        f"{controller.mri}" + _owner(owners, name, item.line),
                    )
        controller._update_writeable()

    def check_unmade(self, controller: Controller, item: Item) -> None:
        """The phases of a part class not made (checking): each must be one
        of the controller's model."""
        factory = item.factory
        if not isinstance(factory, type):
            return
        for phase, func in hook_functions(factory):
            # as add_part matches them: by name, else by the builtin role
            if controller.resolve_phase(phase) is None:
                self.problems.add(
                    item.file,
                    item.line,
                    f"{item.kind}: {controller.mri}: part "
                    f"{item.kwargs.get('name')!r} hooks {func.__name__} into phase"
                    f" {phase!r}, which model {controller.model.name} does not have",
                )

    def commit(self, add: bool = True) -> None:
        """Add every controller built (if ``add``), or raise every problem."""
        seen: dict[str, _Built] = {}
        for built in self.built:
            mri = built.controller.mri
            if mri in self.process.mris:
                self.problems.add(
                    built.file,
                    built.line,
                    f"a block with mri '{mri}' already exists in {self.process.name}",
                )
            elif mri in seen:
                first = seen[mri]
                self.problems.add(
                    built.file,
                    built.line,
                    f"mri '{mri}' is built twice (first at {first.file}:{first.line})",
                )
            seen[mri] = built
        self.problems.problems.sort(key=lambda p: (p.file, p.line))
        self.problems.raise_if_any()
        if add:
            for built in self.built:
                self.process.add_controller(built.controller)


def _why(error: BaseException) -> str:
    if isinstance(error, ValueError | TypeError):
        return str(error)
    return f"{type(error).__name__}: {error}"


def _owner(owners: dict[str, int], name: str, line: int) -> str:
    first = owners.get(name)
    return f" (made at line {first})" if first is not None and first != line else ""


def _build(
    process: Process,
    plans: Sequence[BlockPlan],
    problems: Problems,
    make: Callable[[Callable[..., Any]], bool] = make_everything,
    add: bool = True,
) -> list[Controller | None]:
    builder = _Builder(process, problems, make)
    tops = [builder.block(plan) for plan in plans]
    builder.commit(add)
    return tops


def _plan_block(
    process: Process,
    expanded: ExpandedBlock,
    search_path: Sequence[PathLike],
    file: str | None,
    line: int,
) -> tuple[BlockPlan, Problems]:
    problems = Problems()
    made = set(process.mris) | {b.mri for b in expanded.walk()}
    planner = Planner(search_path, made, problems)
    return planner.block(expanded, file or str(expanded.path), line), problems


def build_block(
    process: Process,
    expanded: ExpandedBlock,
    search_path: Sequence[PathLike] = (),
    *,
    file: str | None = None,
    line: int = 1,
) -> Controller:
    """Build ``expanded`` (children first) and add it all to ``process``.

    Returns the top block's controller. ``file``/``line`` say where the
    block was asked for, for messages. Raises ConfigError (and adds
    nothing) if anything is wrong.
    """
    plan, problems = _plan_block(process, expanded, search_path, file, line)
    (controller,) = _build(process, [plan], problems)
    assert controller is not None
    return controller


def check_block(
    expanded: ExpandedBlock,
    search_path: Sequence[PathLike] = (),
    *,
    file: str | None = None,
    line: int = 1,
) -> None:
    """Raise ConfigError with every problem building ``expanded`` would meet,
    running no code but malcolm's own.

    Every class is imported and inspected (keywords, annotations, hook
    functions, timeouts); only malcolm's own controllers and parts are made,
    into a throwaway process, and never started.
    """
    process = Process("check")
    plan, problems = _plan_block(process, expanded, search_path, file, line)
    _build(process, [plan], problems, make_malcolm_own, add=False)


def _plan_process(
    process: Process,
    path: PathLike,
    search_path: Sequence[PathLike],
    defines: Mapping[str, Any] | None,
) -> tuple[list[BlockPlan], Problems]:
    spec = load_process_file(path, search_path, defines)
    blocks = expand_process(spec, search_path)
    problems = Problems()
    made = set(process.mris) | {b.mri for block in blocks for b in block.walk()}
    planner = Planner(search_path, made, problems)
    plans = [
        planner.block(block, block_spec.file, block_spec.line)
        for block_spec, block in zip(spec.blocks, blocks)
    ]
    return plans, problems


def build_process(
    path: PathLike,
    search_path: Sequence[PathLike] = (),
    process: Process | None = None,
    defines: Mapping[str, Any] | None = None,
) -> Process:
    """Build every block a process file asks for into ``process`` (a new
    Process named after the file by default), nothing if anything is wrong.

    ``defines`` replaces the values of the file's ``define.<Type>`` sections.
    """
    if process is None:
        process = Process(Path(path).stem)
    plans, problems = _plan_process(process, path, search_path, defines)
    _build(process, plans, problems)
    return process


def check_process(path: PathLike, search_path: Sequence[PathLike] = ()) -> None:
    """Raise ConfigError with every problem :func:`build_process` would meet,
    running no code but malcolm's own (see :func:`check_block`)."""
    process = Process("check")
    plans, problems = _plan_process(process, path, search_path, None)
    _build(process, plans, problems, make_malcolm_own, add=False)


def build_definition(
    path_or_name: PathLike,
    values: Mapping[str, Any] | None = None,
    mri: str | None = None,
    search_path: Sequence[PathLike] = (),
    process: Process | None = None,
) -> Process:
    """Build one definition (a file, or a dotted name on the search path)
    with ``values`` as its block ``mri`` (default: the definition's name)."""
    text = os.fspath(path_or_name)
    if isinstance(path_or_name, os.PathLike) or text.endswith((".yaml", ".yml")):
        path = Path(text)
        name = path.stem
    else:
        path = find_definition(text, search_path)
        name = text
    definition = load_definition(path, name=name)
    expanded = expand(definition, values or {}, search_path, mri=mri)
    if process is None:
        process = Process(expanded.mri)
    build_block(process, expanded, search_path)
    return process

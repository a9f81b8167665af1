"""Plan the blocks an expanded definition makes, without making anything.

:func:`plan_block` turns an :class:`~malcolm.config.definitions.ExpandedBlock`
into a :class:`BlockPlan`: the controller and the parts to make, each with
the factory the registry gives for its kind and the keyword arguments its
section gives, and the blocks to make first (``block.X`` children and the
soft stand-ins of ``client.X`` sections; see ``docs/definitions.md``).

Everything that can be known without calling a factory is checked here, at
the line of the section or key: an unknown or refused kind, keywords the
factory does not take or must have, a value of the wrong simple type, a
``phase_timeout`` that is not a positive finite number of seconds, a hook
function that cannot take ``(task, device)``, two parts with one name. An
item with a problem has no factory: it will not be made.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from malcolm.controllers.base import Controller
from malcolm.parts.base import ChildPart, Part
from malcolm.parts.soft import GroupPart

from . import builtin
from .arguments import argument_problems, factory_name, needs
from .definitions import (
    ClientRef,
    ExpandedBlock,
    PathLike,
    expand,
    find_definition,
    load_definition,
)
from .errors import ConfigError, Problems
from .inspection import hook_problems, timeout_problems
from .registry import lookup
from .remote import make_remote_block, parse_remote
from .yamlsections import Section, split_kind

__all__ = ["BlockPlan", "Item", "part_kind", "plan_block"]

#: constructor keywords the builder gives a controller itself
CONTROLLER_RESERVED = ("mri", "parts")

LineOf = Callable[[tuple[Any, ...]], int]


def part_kind(part: str) -> str:
    """The section kind of a ``part:`` value: ``PosPluginPart`` ->
    ``parts.PosPluginPart``; ``parts.X`` and import paths are kept."""
    return part if part.startswith("parts.") else f"parts.{part}"


@dataclass
class Item:
    """One controller or part to make: where it was written and how."""

    kind: str
    file: str
    line: int
    #: what makes it; None if it cannot be made (a problem says why)
    factory: Callable[..., Any] | None
    kwargs: dict[str, Any]
    line_of: LineOf

    @property
    def param_lines(self) -> dict[str, int]:
        return {key: self.line_of((key,)) for key in self.kwargs}


@dataclass
class BlockPlan:
    """One block to make: its controller, its parts in section order, and
    the blocks to make before it (children, stand-ins)."""

    mri: str
    file: str  #: where the block was asked for
    line: int
    controller: Item | None
    parts: list[Item] = field(default_factory=list)
    before: list[BlockPlan] = field(default_factory=list)
    #: the client this block stands in for, if it is a soft stand-in
    standin: ClientRef | None = None

    def walk(self) -> list[BlockPlan]:
        """Every block of the plan in the order to make them."""
        out: list[BlockPlan] = []
        for plan in self.before:
            out += plan.walk()
        return [*out, self]


def _fixed_line(line: int) -> LineOf:
    return lambda path: line


class Planner:
    """Plans blocks, collecting every problem in ``problems``."""

    def __init__(
        self, search_path: Sequence[PathLike], made: set[str], problems: Problems
    ) -> None:
        self.search_path = search_path
        #: mris that will exist (planned, or already in the process)
        self.made = made
        self.problems = problems
        #: definitions whose stand-ins are being planned (to stop cycles)
        self.standing: list[str] = []
        #: mri -> address of the blocks mirrored from other processes
        self.remotes: dict[str, str] = {}

    def block(
        self,
        expanded: ExpandedBlock,
        file: str,
        line: int,
        standin: ClientRef | None = None,
    ) -> BlockPlan:
        plan = BlockPlan(expanded.mri, file, line, self.controller(expanded))
        plan.standin = standin
        for child in expanded.children:
            plan.before.append(self.block(child.block, child.file, child.line))
        items = [self.group_item(s) for s in expanded.groups]
        names: dict[str, int] = {}
        items += [self.section_item(s, names) for s in expanded.sections]
        for child in expanded.children:
            items.append(
                self.child_item(
                    child.part, child.name, child.block.mri, {}, child.file, child.line
                )
            )
        for client in expanded.clients:
            mri = client.fullname
            if "://" in mri:
                mri, remote = self.remote(client)
                plan.before += remote
            elif client.fullname not in self.made:
                plan.before += self.standin(client)
            items.append(
                self.child_item(
                    client.part,
                    client.name,
                    mri,
                    client.params,
                    client.file,
                    client.line,
                )
            )
        items.sort(key=lambda item: item.line)
        for item in items:
            self.check_part(item)
        self.check_names(expanded.mri, items)
        plan.parts = items
        return plan

    # ---- the controller
    def controller(self, expanded: ExpandedBlock) -> Item | None:
        section = expanded.controller
        if section is None:
            path = str(expanded.path)
            kwargs = {"mri": expanded.mri, "parts": ()}
            factory = builtin.DEFAULT_CONTROLLER
            return Item(
                "controller.StatefulController",
                path,
                1,
                factory,
                kwargs,
                _fixed_line(1),
            )
        factory = self.lookup(section)
        for key in CONTROLLER_RESERVED:
            if key in section.params:
                self.add(
                    section,
                    (key,),
                    f"{section.kind}: '{key}' is given by the builder, not the "
                    "definition",
                )
                factory = None
        kwargs = {"mri": expanded.mri, **section.params, "parts": ()}
        item = Item(
            section.kind, section.file, section.line, factory, kwargs, section.line_of
        )
        if item.factory is None:
            return None
        controller_class = item.factory
        if inspect.isclass(controller_class) and not issubclass(
            controller_class, Controller
        ):
            name = factory_name(controller_class)
            self.refuse(item, f"{item.kind} names {name}, which is not a Controller")
            return None
        self.check_arguments(item)
        for path, message in timeout_problems(controller_class, item.kwargs):
            self.refuse(item, f"{item.kind}: {message}", path)
        return item if item.factory is not None else None

    # ---- parts
    def group_item(self, section: Section) -> Item:
        return Item(
            section.kind,
            section.file,
            section.line,
            GroupPart,
            dict(section.params),
            section.line_of,
        )

    def section_item(self, section: Section, names: dict[str, int]) -> Item:
        kwargs = dict(section.params)
        item = Item(
            section.kind,
            section.file,
            section.line,
            self.lookup(section),
            kwargs,
            section.line_of,
        )
        if item.factory is not None and "name" not in kwargs:
            if needs(item.factory, "name"):
                base = split_kind(section.kind)[1]
                base = base.rpartition(":")[2].rpartition(".")[2]
                names[base] = names.get(base, 0) + 1
                kwargs["name"] = base if names[base] == 1 else f"{base}{names[base]}"
        return item

    def child_item(
        self,
        part: str | None,
        name: str,
        mri: str,
        params: Mapping[str, Any],
        file: str,
        line: int,
    ) -> Item:
        kind = "ChildPart" if part is None else part_kind(part)
        factory: Callable[..., Any] | None = ChildPart
        if part is not None:
            try:
                factory = lookup(kind, file, line)
            except ConfigError as error:
                self.problems.problems.extend(error.problems)
                factory = None
        item = Item(
            kind, file, line, factory, {"name": name, "mri": mri}, _fixed_line(line)
        )
        for key, value in params.items():
            if key in ("name", "mri"):
                self.refuse(item, f"'{key}' is given by the builder")
            item.kwargs[key] = value
        return item

    def check_part(self, item: Item) -> None:
        """Arguments and hook functions of a part's class, without making it."""
        factory = item.factory
        if factory is None:
            return
        if inspect.isclass(factory) and not issubclass(factory, Part):
            note = ""
            if factory in builtin.DESIGN_KINDS.values():
                note = " (a saved-design record: read it with load_design)"
            self.refuse(item, f"{item.kind} makes {factory.__name__}, not a Part{note}")
            return
        self.check_arguments(item)
        if item.factory is not None and inspect.isclass(factory):
            name = item.kwargs.get("name", factory.__name__)
            for problem in hook_problems(factory, str(name)):
                self.refuse(item, f"{item.kind}: {problem}")

    def check_names(self, mri: str, items: list[Item]) -> None:
        owners: dict[str, int] = {}
        for item in items:
            name = item.kwargs.get("name")
            if item.factory is None or not isinstance(name, str):
                continue
            if name in owners:
                self.refuse(
                    item,
                    f"{item.kind}: {mri} already has a part called '{name}' "
                    f"(line {owners[name]})",
                )
            else:
                owners[name] = item.line

    # ---- clients of blocks in other processes (malcolm.config.remote)
    def remote(self, client: ClientRef) -> tuple[str, list[BlockPlan]]:
        """The local mri of a ``pva://`` client and the plan of the block
        mirroring it (none if another client of it made one already)."""
        try:
            name = parse_remote(client.fullname)
        except ValueError as error:
            self.problems.add(
                client.file, client.line, f"client '{client.name}': {error}"
            )
            return client.fullname, []
        assert name is not None
        known = self.remotes.get(name.mri)
        if known == name.address:
            return name.mri, []
        if known is not None or name.mri in self.made:
            elsewhere = f"pva://{known}" if known else "this process"
            self.problems.add(
                client.file,
                client.line,
                f"client '{client.name}': {name} would mirror block '{name.mri}'"
                f" here, which is already a block of {elsewhere}",
            )
            return name.mri, []
        self.remotes[name.mri] = name.address
        self.made.add(name.mri)
        item = Item(
            f"client {name}",
            client.file,
            client.line,
            make_remote_block,
            {"mri": name.mri, "address": name.address},
            _fixed_line(client.line),
        )
        return name.mri, [BlockPlan(name.mri, client.file, client.line, item)]

    # ---- stand-ins
    def standin(self, client: ClientRef) -> list[BlockPlan]:
        """The plans of a soft block of the client's definition at its fullname."""
        if client.definition in self.standing:
            self.problems.add(
                client.file,
                client.line,
                f"cannot make a stand-in for '{client.fullname}': "
                f"{client.definition} needs stand-ins of itself "
                f"({' -> '.join([*self.standing, client.definition])})",
            )
            return []
        self.standing.append(client.definition)
        try:
            expanded = self.expand_standin(client)
            if expanded is None:
                return []
            self.made.update(b.mri for b in expanded.walk())
            return [self.block(expanded, client.file, client.line, standin=client)]
        finally:
            self.standing.pop()

    def expand_standin(self, client: ClientRef) -> ExpandedBlock | None:
        try:
            path = find_definition(
                client.definition, self.search_path, file=client.file, line=client.line
            )
            definition = load_definition(path, name=client.definition)
            declared = {p.name: p for p in definition.params}
            values = {k: v for k, v in client.params.items() if k in declared}
            for p in definition.params:
                if p.required and p.name not in values and p.type == "String":
                    values[p.name] = client.fullname
            return expand(
                definition,
                values,
                self.search_path,
                mri=client.fullname,
                file=client.file,
                line=client.line,
            )
        except ConfigError as error:
            self.problems.problems.extend(error.problems)
            return None

    # ---- helpers
    def lookup(self, section: Section) -> Callable[..., Any] | None:
        try:
            return lookup(section.kind, section.file, section.line)
        except ConfigError as error:
            self.problems.problems.extend(error.problems)
            return None

    def check_arguments(self, item: Item) -> None:
        assert item.factory is not None
        found = argument_problems(
            item.factory, item.kwargs, item.kind, item.file, item.line, item.param_lines
        )
        if found:
            self.problems.problems.extend(found)
            item.factory = None

    def add(self, section: Section, path: tuple[Any, ...], message: str) -> None:
        self.problems.add(section.file, section.line_of(path), message)

    def refuse(self, item: Item, message: str, path: tuple[Any, ...] = ()) -> None:
        """Note a problem with ``item`` (at the line of ``path``); it will
        not be made."""
        self.problems.add(item.file, item.line_of(path) if path else item.line, message)
        item.factory = None


def plan_block(
    expanded: ExpandedBlock,
    search_path: Sequence[PathLike] = (),
    *,
    file: str | None = None,
    line: int = 1,
    made: set[str] | None = None,
) -> tuple[BlockPlan, Problems]:
    """The plan of ``expanded`` and every problem found making it.

    ``made`` holds the mris that will exist besides this block's tree (a
    client whose fullname is one of them needs no stand-in).
    """
    problems = Problems()
    known = set(made or ()) | {b.mri for b in expanded.walk()}
    planner = Planner(search_path, known, problems)
    plan = planner.block(expanded, file or str(expanded.path), line)
    return plan, problems

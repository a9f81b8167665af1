"""Build running blocks from definitions: controllers, parts and child blocks.

:func:`build_block` turns an :class:`~malcolm.config.definitions.ExpandedBlock`
into a controller with its parts, after building every child block it makes
(``block.X``) with its own controller:

- ``controller.X`` gives the controller class (a StatefulController if the
  definition has none); its keys are constructor keywords (``description``,
  ``design``...), the builder passes ``mri`` and ``parts``;
- every other section (``ca.*``, ``parts.*``...) is one part, made by the
  factory :func:`~malcolm.config.registry.lookup` gives for its kind, with
  the section's keys as constructor keywords. A part whose constructor
  takes a ``name`` that the section does not give is named after the kind
  (``parts.DetectorPart`` -> ``DetectorPart``, then ``DetectorPart2``...);
- ``gui.Group`` sections make a :class:`~malcolm.parts.soft.GroupPart`;
- a ``block.X`` child is controlled from the parent by the part its ``part:``
  names (``part: PosPluginPart`` -> kind ``parts.PosPluginPart``, called
  with ``name=<child name>, mri=<child mri>``); without ``part:``, a plain
  :class:`~malcolm.parts.base.ChildPart`;
- a ``client.X`` section is the same, for the existing block ``fullname``;
  its other keys (``readonly: False``) are keywords of the part. If nothing
  in the process (or being built with it) has that mri, the builder makes
  a *soft stand-in* block from the client's definition, so the definition
  still loads: it takes the client's keys that are parameters of that
  definition, and the fullname for any required String parameter missing.

Parts are added in the order their sections are written. An unknown
keyword, a missing argument, a failing constructor, a field added twice:
each is a ConfigError naming the ``file:line`` of its section (or key), and
all problems are reported together. Nothing is added to the process unless
the whole build succeeded.
"""

from __future__ import annotations

import inspect
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from malcolm.controllers.base import Controller
from malcolm.core import Process
from malcolm.parts.base import ChildPart, Part
from malcolm.parts.soft import GroupPart

from . import builtin
from .definitions import (
    ClientRef,
    ExpandedBlock,
    PathLike,
    expand,
    find_definition,
    load_definition,
)
from .errors import ConfigError, Problems, did_you_mean
from .process_file import expand_process, load_process_file
from .registry import lookup
from .yamlsections import Section, split_kind

__all__ = ["build_block", "build_definition", "build_process", "part_kind"]

_KEYWORDS = (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
#: constructor keywords the builder gives a controller itself
_CONTROLLER_RESERVED = ("mri", "parts")


def part_kind(part: str) -> str:
    """The section kind of a ``part:`` value: ``PosPluginPart`` ->
    ``parts.PosPluginPart``; ``parts.X`` and import paths are kept."""
    return part if part.startswith("parts.") else f"parts.{part}"


@dataclass
class _Item:
    """One part to make: where it was written and how to make it."""

    line: int
    file: str
    kind: str
    factory: Callable[..., Any] | None
    kwargs: dict[str, Any]
    param_lines: Mapping[str, int]


@dataclass
class _Built:
    controller: Controller
    file: str
    line: int


class _Builder:
    def __init__(
        self,
        process: Process,
        search_path: Sequence[PathLike],
        planned: set[str],
    ) -> None:
        self.process = process
        self.search_path = search_path
        self.problems = Problems()
        self.built: list[_Built] = []
        #: mris that will exist once the build is added to the process
        self.made = set(planned) | set(process.mris)
        #: definitions whose stand-ins are being built (to stop cycles)
        self.standing: list[str] = []

    # ---- blocks
    def block(self, expanded: ExpandedBlock, file: str, line: int) -> Controller | None:
        for child in expanded.children:
            self.block(child.block, child.file, child.line)
        controller = self.controller(expanded)
        items = [self.group_item(s) for s in expanded.groups]
        names: dict[str, int] = {}
        for section in expanded.sections:
            items.append(self.section_item(section, names))
        for child in expanded.children:
            items.append(
                self.child_item(
                    child.part, child.name, child.block.mri, {}, child.file, child.line
                )
            )
        for client in expanded.clients:
            if client.fullname not in self.made:
                self.standin(client)
            items.append(
                self.child_item(
                    client.part,
                    client.name,
                    client.fullname,
                    client.params,
                    client.file,
                    client.line,
                )
            )
        items.sort(key=lambda item: item.line)
        parts = [(item, self.make_part(item)) for item in items]
        if controller is None:
            return None
        self.add_parts(controller, parts)
        self.built.append(_Built(controller, file, line))
        return controller

    def controller(self, expanded: ExpandedBlock) -> Controller | None:
        section = expanded.controller
        if section is None:
            factory: Callable[..., Any] = builtin.DEFAULT_CONTROLLER
            kind, file, line, params, lines = (
                "controller.StatefulController",
                str(expanded.path),
                1,
                {},
                {},
            )
        else:
            kind, file, line = section.kind, section.file, section.line
            params, lines = dict(section.params), section.param_lines
            try:
                factory = lookup(kind, file, line)
            except ConfigError as error:
                self.problems.problems.extend(error.problems)
                return None
            for key in _CONTROLLER_RESERVED:
                if key in params:
                    self.problems.add(
                        file,
                        lines.get(key, line),
                        f"{kind}: '{key}' is given by the builder, not the definition",
                    )
                    return None
        item = _Item(line, file, kind, factory, {"mri": expanded.mri, **params}, lines)
        controller = self.call(item, {**item.kwargs, "parts": ()})
        if controller is not None and not isinstance(controller, Controller):
            self.problems.add(
                file,
                line,
                f"{kind} makes {type(controller).__name__}, not a Controller",
            )
            return None
        return controller

    def standin(self, client: ClientRef) -> None:
        """Make a soft block of the client's definition at its fullname."""
        if client.definition in self.standing:
            self.problems.add(
                client.file,
                client.line,
                f"cannot make a stand-in for '{client.fullname}': "
                f"{client.definition} needs stand-ins of itself "
                f"({' -> '.join([*self.standing, client.definition])})",
            )
            return
        self.standing.append(client.definition)
        try:
            self._standin(client)
        finally:
            self.standing.pop()

    def _standin(self, client: ClientRef) -> None:
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
            expanded = expand(
                definition,
                values,
                self.search_path,
                mri=client.fullname,
                file=client.file,
                line=client.line,
            )
        except ConfigError as error:
            self.problems.problems.extend(error.problems)
            return
        self.made.update(b.mri for b in expanded.walk())
        controller = self.block(expanded, client.file, client.line)
        if controller is not None:
            meta = controller.block.meta
            meta.description = meta.description or (
                f"Soft stand-in for {client.definition} (client '{client.name}' "
                f"at {client.file}:{client.line})"
            )
            meta.tags = (*meta.tags, "standin")

    # ---- parts
    def group_item(self, section: Section) -> _Item:
        return _Item(
            section.line,
            section.file,
            section.kind,
            GroupPart,
            dict(section.params),
            section.param_lines,
        )

    def section_item(self, section: Section, names: dict[str, int]) -> _Item:
        kwargs = dict(section.params)
        item = _Item(
            section.line, section.file, section.kind, None, kwargs, section.param_lines
        )
        try:
            item.factory = lookup(section.kind, section.file, section.line)
        except ConfigError as error:
            self.problems.problems.extend(error.problems)
            return item
        if "name" not in kwargs and _needs(item.factory, "name"):
            base = split_kind(section.kind)[1].rpartition(":")[2].rpartition(".")[2]
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
    ) -> _Item:
        kind = "ChildPart" if part is None else part_kind(part)
        item = _Item(line, file, kind, ChildPart, {"name": name, "mri": mri}, {})
        if part is not None:
            try:
                item.factory = lookup(kind, file, line)
            except ConfigError as error:
                self.problems.problems.extend(error.problems)
                item.factory = None
        for key, value in params.items():
            if key in ("name", "mri"):
                self.problems.add(file, line, f"'{key}' is given by the builder")
                item.factory = None
            item.kwargs[key] = value
        return item

    def make_part(self, item: _Item) -> Part | None:
        if item.factory is None:
            return None
        part = self.call(item, item.kwargs)
        if part is not None and not isinstance(part, Part):
            note = ""
            if isinstance(part, tuple(builtin.DESIGN_KINDS.values())):
                note = " (a saved-design record: read it with load_design)"
            self.problems.add(
                item.file,
                item.line,
                f"{item.kind} makes {type(part).__name__}, not a Part{note}",
            )
            return None
        return part

    def add_parts(
        self, controller: Controller, parts: list[tuple[_Item, Part | None]]
    ) -> None:
        owners: dict[str, int] = {}
        for item, part in parts:
            if part is None:
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
                if controller.block[name] is not old:
                    self.problems.add(
                        item.file,
                        item.line,
                        f"{item.kind}: '{name}' is already a field of "
                        f"{controller.mri}" + _owner(owners, name, item.line),
                    )
        controller._update_writeable()

    def call(self, item: _Item, kwargs: dict[str, Any]) -> Any:
        """``factory(**kwargs)``; problems at the section's lines, else None."""
        factory = item.factory
        assert factory is not None
        try:
            signature = inspect.signature(factory)
        except (TypeError, ValueError):
            signature = None
        if signature is not None:
            params = signature.parameters
            takes = [n for n, p in params.items() if p.kind in _KEYWORDS]
            var_kw = any(p.kind is p.VAR_KEYWORD for p in params.values())
            ok = True
            for key in kwargs:
                if key not in takes and not var_kw:
                    ok = False
                    self.problems.add(
                        item.file,
                        item.param_lines.get(key, item.line),
                        f"{item.kind}: unknown parameter '{key}' "
                        f"({_name(factory)} takes {', '.join(takes) or 'nothing'})"
                        + did_you_mean(key, takes),
                    )
            for name in takes:
                param = params[name]
                if param.default is param.empty and name not in kwargs:
                    ok = False
                    self.problems.add(
                        item.file,
                        item.line,
                        f"{item.kind}: missing required parameter '{name}'",
                    )
            for key, value in kwargs.items():
                want = _annotation(factory, key)
                if want is not None and not _fits(value, want):
                    ok = False
                    self.problems.add(
                        item.file,
                        item.param_lines.get(key, item.line),
                        f"{item.kind}: '{key}' must be {_say(want)}, not {value!r}",
                    )
            if not ok:
                return None
        try:
            return factory(**kwargs)
        except ConfigError as error:
            self.problems.problems.extend(error.problems)
        except Exception as error:
            self.problems.add(item.file, item.line, f"{item.kind}: {_why(error)}")
        return None

    # ---- adding
    def commit(self) -> None:
        """Add every controller built, or raise every problem and add none."""
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
        for built in self.built:
            self.process.add_controller(built.controller)


def _needs(factory: Callable[..., Any], name: str) -> bool:
    """True if ``factory`` has a keyword ``name`` without a default."""
    try:
        params = inspect.signature(factory).parameters
    except (TypeError, ValueError):
        return False
    param = params.get(name)
    return (
        param is not None and param.kind in _KEYWORDS and param.default is param.empty
    )


def _name(factory: Callable[..., Any]) -> str:
    return getattr(factory, "__qualname__", None) or repr(factory)


def _why(error: BaseException) -> str:
    if isinstance(error, ValueError | TypeError):
        return str(error)
    return f"{type(error).__name__}: {error}"


def _owner(owners: dict[str, int], name: str, line: int) -> str:
    first = owners.get(name)
    return f" (made at line {first})" if first is not None and first != line else ""


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
    builder = _Builder(process, search_path, {b.mri for b in expanded.walk()})
    controller = builder.block(expanded, file or str(expanded.path), line)
    builder.commit()
    assert controller is not None
    return controller


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
    spec = load_process_file(path, search_path, defines)
    blocks = expand_process(spec, search_path)
    if process is None:
        process = Process(Path(path).stem)
    planned = {b.mri for block in blocks for b in block.walk()}
    builder = _Builder(process, search_path, planned)
    for block_spec, block in zip(spec.blocks, blocks):
        builder.block(block, block_spec.file, block_spec.line)
    builder.commit()
    return process


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


_SIMPLE = {"str": (str,), "float": (int, float), "int": (int,), "bool": (bool,)}


def _annotation(factory: Any, key: str) -> str | None:
    """The simple type (str/float/int/bool, maybe "| None") a keyword declares."""
    target = factory.__init__ if inspect.isclass(factory) else factory
    raw = getattr(target, "__annotations__", {}).get(key)
    if not isinstance(raw, str):
        raw = getattr(raw, "__name__", None) if raw is not None else None
    if raw is None:
        return None
    parts = {p.strip() for p in raw.split("|")}
    if parts - {"None"} and parts - {"None"} <= set(_SIMPLE) | {"Path"}:
        return " or ".join(sorted(parts))
    return None


def _fits(value: Any, want: str) -> bool:
    parts = set(want.split(" or "))
    if value is None:
        return "None" in parts
    if isinstance(value, bool):
        return "bool" in parts
    for name in parts:
        if name == "Path" and isinstance(value, str):
            return True
        if name in _SIMPLE and isinstance(value, _SIMPLE[name]):
            return True
    return False


_WORDS = {"str": "text", "float": "a number", "int": "an integer",
          "bool": "a boolean", "Path": "a path"}  # fmt: skip


def _say(want: str) -> str:
    parts = want.split(" or ")
    words = sorted({_WORDS[p] for p in parts if p in _WORDS})
    return " or ".join(words) + (" (or nothing)" if "None" in parts else "")

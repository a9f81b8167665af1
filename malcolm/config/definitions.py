"""Find, load and expand block definitions.

A definition named ``ADCore.PositionPlugin`` lives in
``<dir>/ADCore/PositionPlugin.yaml`` for the first ``<dir>`` of the search
path that has it; the search path is the package's ``malcolm/blocks/``
directory followed by the directories the caller gives.

Expanding a definition resolves its ``init.*`` parameters against given
values, substitutes them (and ``{mri}``, the block's own mri) into every
other section, and expands each ``block.X`` section into a child block:

- ``name`` is the child's name in its parent; the child's mri is
  ``<parent mri>:<name>`` (so ``BL18I:Z1`` + ``PCOMP1`` gives
  ``BL18I:Z1:PCOMP1``, as in the design's palette table);
- ``part`` (optional) names the part that controls the child in the parent;
- every other key is an init value of the child.

``client.X`` sections attach to an existing block (``name``, ``fullname``,
optional ``part``, other keys kept as they are) and are not expanded.
"""

from __future__ import annotations

import dataclasses
import os
import re
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from malcolm.filecache import FileCache, Snapshot

from .errors import ConfigError, Problems, did_you_mean
from .params import RESERVED_NAMES, InitParam, param_from_section, resolve_params
from .substitute import substitute_section
from .yamlsections import Section, load_sections

#: Definitions shipped with malcolm; always first on the search path.
BLOCKS_DIR = Path(__file__).resolve().parent.parent / "blocks"
#: The only gui section the language knows.
GUI_KINDS = ("gui.Group",)

_DEFINITION_RE = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_-]*(?:\.[A-Za-z0-9_][\w-]*)*")
_CHILD_NAME_RE = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]*")
#: Text parameters each loader-handled namespace requires.
_NEEDS = {"gui": ("name",), "block": ("name",), "client": ("name", "fullname")}

PathLike = str | os.PathLike[str]


def full_search_path(search_path: Iterable[PathLike] = ()) -> list[Path]:
    """``malcolm/blocks`` followed by ``search_path``, without repeats."""
    dirs: list[Path] = []
    for d in (BLOCKS_DIR, *map(Path, search_path)):
        if d not in dirs:
            dirs.append(d)
    return dirs


def available_definitions(search_path: Iterable[PathLike] = ()) -> list[str]:
    """The dotted names of every definition on the search path, sorted."""
    names: set[str] = set()
    for d in full_search_path(search_path):
        if d.is_dir():
            for path in d.rglob("*.yaml"):
                names.add(".".join(path.relative_to(d).with_suffix("").parts))
    return sorted(names)


def find_definition(
    name: str,
    search_path: Sequence[PathLike] = (),
    *,
    file: str = "<search>",
    line: int = 1,
) -> Path:
    """The file of definition ``name``; ConfigError at ``file:line`` if none."""
    if not _DEFINITION_RE.fullmatch(name):
        raise ConfigError.at(file, line, f"invalid definition name '{name}'")
    relative = Path(*name.split(".")).with_suffix(".yaml")
    dirs = full_search_path(search_path)
    for d in dirs:
        if (d / relative).is_file():
            return d / relative
    looked = ", ".join(str(d) for d in dirs)
    raise ConfigError.at(
        file,
        line,
        f"no definition '{name}' ({relative} not found in: {looked})"
        + did_you_mean(name, available_definitions(search_path)),
    )


@dataclass(frozen=True)
class Definition:
    """A loaded, checked definition file; nothing substituted yet.

    Shared by every block made from the file (see :func:`load_definition`):
    expanding copies what it substitutes and changes nothing here.
    """

    path: Path
    params: tuple[InitParam, ...]
    sections: tuple[Section, ...]  #: every section except init.*, in order
    name: str = ""  #: dotted name, e.g. "ADCore.PositionPlugin"


#: loaded definitions by (file as given, file resolved, name), kept while the
#: file is unchanged; one with problems is read again every time
_DEFINITIONS: FileCache[Definition] = FileCache()


def load_definition(path: PathLike, *, name: str | None = None) -> Definition:
    """Load a definition and check it, raising every problem found at once.

    Checks: parameter declarations, section names, at most one controller,
    ``name`` of block/client sections, ``gui.Group`` names used by
    ``group:``, and that every ``{reference}`` names a declared parameter.
    A file is read once per process while it is unchanged: a thousand blocks
    made from one definition share one :class:`Definition`.
    """
    path = Path(path)
    key = (str(path), path.resolve(), name)
    found = _DEFINITIONS.get(key)
    if found is not None:
        return found
    snapshot = Snapshot.take(path)
    definition = _read_definition(path, name)
    if snapshot is not None:
        _DEFINITIONS.put(key, snapshot, definition)
    return definition


def _read_definition(path: Path, name: str | None) -> Definition:
    file = str(path)
    problems = Problems()
    params: list[InitParam] = []
    sections: list[Section] = []
    for section in load_sections(path):
        if section.namespace == "init":
            with problems.collect():
                param = param_from_section(section)
                first = next((p for p in params if p.name == param.name), None)
                if first:
                    problems.add(
                        file,
                        section.line,
                        f"parameter '{param.name}' declared twice "
                        f"(first at line {first.line})",
                    )
                else:
                    params.append(param)
        elif not section.name:
            problems.add(
                file,
                section.line,
                f"section '{section.kind}' must be written namespace.Name",
            )
        else:
            sections.append(section)
    _check_sections(sections, problems)
    names = {p.name: "" for p in params} | {n: "" for n in RESERVED_NAMES}
    for section in sections:
        with problems.collect():
            substitute_section(section, names)
    problems.problems.sort(key=lambda p: p.line)
    problems.raise_if_any()
    return Definition(path, tuple(params), tuple(sections), name or path.stem)


def _check_sections(sections: list[Section], problems: Problems) -> None:
    controller: Section | None = None
    groups: dict[str, int] = {}
    for s in sections:
        if s.namespace == "controller":
            if controller:
                problems.add(
                    s.file,
                    s.line,
                    f"a block has one controller ({controller.kind} "
                    f"at line {controller.line})",
                )
            controller = s
        elif s.namespace == "gui" and s.kind not in GUI_KINDS:
            problems.add(
                s.file,
                s.line,
                f"unknown section type '{s.kind}'" + did_you_mean(s.kind, GUI_KINDS),
            )
        elif s.namespace == "block" and not _DEFINITION_RE.fullmatch(s.name):
            problems.add(s.file, s.line, f"invalid definition name '{s.name}'")
        for key in _NEEDS.get(s.namespace, ()):
            if not isinstance(s.params.get(key), str):
                problems.add(s.file, s.line, f"{s.kind} needs a '{key}' (text)")
        if s.kind == "gui.Group" and isinstance(s.params.get("name"), str):
            groups.setdefault(s.params["name"], s.line)
    for s in sections:
        group = s.params.get("group")
        if s.namespace != "gui" and isinstance(group, str) and "{" not in group:
            if group not in groups:
                problems.add(
                    s.file,
                    s.line_of(("group",)),
                    f"unknown group '{group}'" + did_you_mean(group, groups),
                )


@dataclass(frozen=True)
class ClientRef:
    """A ``client.X`` section: a part attached to a block made elsewhere."""

    definition: str  #: e.g. "ADCore.DetectorDriver"
    name: str
    fullname: str  #: mri of the existing block
    part: str | None
    params: dict[str, Any]  #: the other keys, e.g. {"readonly": False}
    file: str
    line: int


@dataclass(frozen=True)
class ChildBlock:
    """A ``block.X`` section: a child block made by the parent."""

    name: str
    part: str | None
    block: ExpandedBlock
    file: str
    line: int


@dataclass(frozen=True)
class ExpandedBlock:
    """A definition with its parameters resolved and substituted."""

    definition: str
    path: Path
    mri: str
    params: dict[str, Any]
    controller: Section | None = None
    groups: list[Section] = field(default_factory=list)
    #: the sections the registry builds (ca.*, parts.*, fixed.*...), in order
    sections: list[Section] = field(default_factory=list)
    children: list[ChildBlock] = field(default_factory=list)
    clients: list[ClientRef] = field(default_factory=list)

    def walk(self) -> Iterator[ExpandedBlock]:
        """This block, then every descendant, depth first."""
        yield self
        for child in self.children:
            yield from child.block.walk()


def expand(
    definition: Definition,
    values: Mapping[str, Any],
    search_path: Sequence[PathLike] = (),
    *,
    mri: str | None = None,
    file: str | None = None,
    line: int | None = None,
    given_lines: Mapping[str, int] | None = None,
) -> ExpandedBlock:
    """Resolve ``values``, substitute, and expand ``block.X`` children.

    ``mri`` defaults to the definition's name. ``file``/``line``/
    ``given_lines`` locate where ``values`` were written, for messages.
    Raises one ConfigError with every problem found in the tree; a cycle of
    ``block.X`` includes is an error naming the chain.
    """
    where = (file or str(definition.path), line, given_lines or {})
    return _Expander(search_path).expand(
        definition, values, mri or definition.name, where, ()
    )


_Where = tuple[str, int | None, Mapping[str, int]]
_Stack = tuple[tuple[Path, str, str, int], ...]  # (path, name, file, line)


class _Expander:
    def __init__(self, search_path: Sequence[PathLike]) -> None:
        self.search_path = search_path

    def expand(
        self,
        definition: Definition,
        values: Mapping[str, Any],
        mri: str,
        where: _Where,
        stack: _Stack,
    ) -> ExpandedBlock:
        file, line, lines = where
        params = resolve_params(
            definition.params,
            values,
            file,
            line=line,
            given_lines=lines,
            context=definition.name,
        )
        names = {**params, "mri": mri}
        stack = (*stack, (definition.path.resolve(), definition.name, file, line or 1))
        problems = Problems()
        block = ExpandedBlock(definition.name, definition.path, mri, params)
        controller: Section | None = None
        seen: dict[str, int] = {}
        for raw in definition.sections:
            try:
                section = substitute_section(raw, names)
            except ConfigError as error:
                problems.problems.extend(error.problems)
                continue
            ns = section.namespace
            if ns == "controller":
                controller = section
            elif ns == "gui":
                block.groups.append(section)
            elif ns in ("block", "client"):
                name = section.params.get("name")
                if not isinstance(name, str) or not _CHILD_NAME_RE.fullmatch(name):
                    problems.add(
                        section.file,
                        section.line_of(("name",)),
                        f"invalid {ns} name {name!r} (letters, digits, _ . -)",
                    )
                    continue
                if name in seen:
                    problems.add(
                        section.file,
                        section.line,
                        f"two children named '{name}' (first at line {seen[name]})",
                    )
                    continue
                seen[name] = section.line
                with problems.collect():
                    if ns == "client":
                        block.clients.append(_client(section, name))
                    else:
                        block.children.append(self.child(section, name, mri, stack))
            else:
                block.sections.append(section)
        problems.raise_if_any()
        return dataclasses.replace(block, controller=controller)

    def child(self, section: Section, name: str, mri: str, stack: _Stack) -> ChildBlock:
        file, line = section.file, section.line
        path = find_definition(section.name, self.search_path, file=file, line=line)
        if any(p == path.resolve() for p, *_ in stack):
            chain = " -> ".join([*(n for _, n, _, _ in stack), section.name])
            sites = "; ".join(f"{f}:{n}" for _, _, f, n in stack[1:])
            raise ConfigError.at(
                file,
                line,
                f"cycle of block includes: {chain}"
                + (f" (included at {sites}; {file}:{line})" if sites else ""),
            )
        definition = load_definition(path, name=section.name)
        values = {k: v for k, v in section.params.items() if k not in ("name", "part")}
        block = self.expand(
            definition,
            values,
            f"{mri}:{name}",
            (file, line, section.param_lines),
            stack,
        )
        return ChildBlock(name, _part(section), block, file, line)


def _part(section: Section) -> str | None:
    part = section.params.get("part")
    if part is not None and not isinstance(part, str):
        raise ConfigError.at(
            section.file, section.line_of(("part",)), "part must be text"
        )
    return part


def _client(section: Section, name: str) -> ClientRef:
    fullname = section.params.get("fullname")
    if not isinstance(fullname, str) or not fullname:
        raise ConfigError.at(
            section.file,
            section.line_of(("fullname",)),
            f"{section.kind} needs a 'fullname' (the mri of the existing block)",
        )
    rest = {
        k: v for k, v in section.params.items() if k not in ("name", "fullname", "part")
    }
    return ClientRef(
        section.name, name, fullname, _part(section), rest, section.file, section.line
    )

"""Process files: which blocks a malcolm process makes, with their values.

A process file is written in the same section style as a definition::

    include: common.yaml          # or a list; paths relative to this file
    define.String:
        name: beamline
        value: BL18I
    block.demo.Hello:
        mri: {beamline}:HELLO     # required: the new block's mri
        greeting: Hi              # init values of demo/Hello.yaml

Sections are read in order:

- ``include`` reads another process file as if its sections were written at
  that point: it sees the defines made so far, and its defines are visible
  afterwards. A file is read once however often it is included; including a
  file that is still being read is a cycle, an error.
- ``define.String|Int|Float|Boolean`` (``name``, ``value``) makes ``{name}``
  usable in every later value. Defining a name twice is an error.
- ``block.<Definition>`` asks for one block made from a definition; ``mri``
  is required, the other keys are the definition's init values, checked
  against its ``init.*`` declarations. Two blocks with one mri is an error.
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .definitions import (
    Definition,
    ExpandedBlock,
    PathLike,
    expand,
    find_definition,
    load_definition,
)
from .errors import ConfigError, Problems
from .params import (
    RESERVED_NAMES,
    SCALAR_TYPES,
    check_value,
    describe_type,
    resolve_params,
)
from .substitute import substitute_section
from .yamlsections import Section, load_sections

_INCLUDE = "include"


#: what an mri may hold: it names channels, and directories of designs
MRI = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_:.\-]*$")


@dataclass(frozen=True)
class BlockSpec:
    """One ``block.X`` entry of a process file, defines substituted."""

    definition: str  #: e.g. "demo.Hello"
    mri: str
    values: dict[str, Any]  #: init values as given (defaults not applied)
    file: str
    line: int
    value_lines: dict[str, int] = field(default_factory=dict)


@dataclass(frozen=True)
class ProcessSpec:
    """Everything a process file (and its includes) asks for."""

    blocks: list[BlockSpec]
    defines: dict[str, Any]


def load_process_file(
    path: PathLike,
    search_path: Sequence[PathLike] = (),
    defines: Mapping[str, Any] | None = None,
) -> ProcessSpec:
    """Read a process file and its includes; check every block entry.

    Each block's definition must exist on the search path (see
    :func:`~malcolm.config.definitions.find_definition`) and its values must
    match the definition's parameters. ``defines`` replaces the values of
    ``define.<Type>`` sections of those names (checked against their type),
    as ``-D`` does for a compiler; naming one the files never define is an
    error. Raises one ConfigError with every problem found.
    """
    reader = _Reader(search_path, defines or {})
    reader.read(Path(path), ())
    for name in reader.overrides.keys() - reader.define_sites.keys():
        reader.problems.add(str(path), 1, f"no define '{name}' to override")
    reader.problems.raise_if_any()
    return ProcessSpec(reader.blocks, reader.defines)


def expand_process(
    spec: ProcessSpec, search_path: Sequence[PathLike] = ()
) -> list[ExpandedBlock]:
    """Expand every block of ``spec``; every mri in the trees must differ."""
    problems = Problems()
    blocks: list[ExpandedBlock] = []
    for b in spec.blocks:
        with problems.collect():
            path = find_definition(b.definition, search_path, file=b.file, line=b.line)
            definition = load_definition(path, name=b.definition)
            blocks.append(
                expand(
                    definition,
                    b.values,
                    search_path,
                    mri=b.mri,
                    file=b.file,
                    line=b.line,
                    given_lines=b.value_lines,
                )
            )
    seen: dict[str, BlockSpec] = {}
    for spec_block, block in zip(spec.blocks, blocks):
        for made in block.walk():
            if made.mri in seen:
                first = seen[made.mri]
                problems.add(
                    spec_block.file,
                    spec_block.line,
                    f"mri '{made.mri}' is made twice "
                    f"(also by {first.definition} at {first.file}:{first.line})",
                )
            else:
                seen[made.mri] = spec_block
    problems.raise_if_any()
    return blocks


class _Reader:
    def __init__(
        self, search_path: Sequence[PathLike], overrides: Mapping[str, Any]
    ) -> None:
        self.search_path = search_path
        self.overrides = dict(overrides)
        self.problems = Problems()
        self.defines: dict[str, Any] = {}
        self.define_sites: dict[str, str] = {}
        self.blocks: list[BlockSpec] = []
        self.mris: dict[str, BlockSpec] = {}
        self.done: set[Path] = set()
        self.definitions: dict[Path, Definition | None] = {}

    def read(self, path: Path, stack: tuple[tuple[Path, str, int], ...]) -> None:
        self.done.add(path.resolve())
        with self.problems.collect():
            for section in load_sections(path, value_kinds={_INCLUDE}):
                with self.problems.collect():
                    if section.kind == _INCLUDE:
                        self.include(path, section, stack)
                    elif section.namespace == "define":
                        self.define(section)
                    elif section.namespace == "block" and section.name:
                        self.block(section)
                    else:
                        raise ConfigError.at(
                            section.file,
                            section.line,
                            f"unknown section '{section.kind}' in a process file "
                            "(expected include, define.<Type> or block.<Definition>)",
                        )

    def include(self, path: Path, section: Section, stack: tuple) -> None:
        value = section.params.get("value")
        targets = value if isinstance(value, list) else [value]
        for i, target in enumerate(targets):
            line = section.line_of(("value", i) if isinstance(value, list) else ())
            if not isinstance(target, str) or not target:
                self.problems.add(section.file, line, "include needs a file name")
                continue
            included = path.parent / target
            try:
                resolved = included.resolve()
            except (OSError, RuntimeError) as e:  # e.g. a symlink loop
                self.problems.add(section.file, line, f"cannot read include: {e}")
                continue
            chain = (*stack, (path.resolve(), section.file, line))
            if any(p == resolved for p, _, _ in chain):
                files = " -> ".join(f"{f}:{n}" for _, f, n in chain)
                self.problems.add(
                    section.file,
                    line,
                    f"cycle of includes: {files} -> {included}",
                )
            elif resolved in self.done:
                continue
            elif included.is_dir():
                self.problems.add(
                    section.file, line, f"cannot include a directory: {included}"
                )
            elif not included.is_file():
                self.problems.add(section.file, line, f"no such file: {included}")
            else:
                self.read(included, chain)

    def define(self, raw: Section) -> None:
        section = substitute_section(raw, self.defines)
        file, params = section.file, section.params
        if section.name not in SCALAR_TYPES:
            raise ConfigError.at(
                file,
                section.line,
                f"unknown define type '{section.kind}' "
                f"(expected define.{', define.'.join(SCALAR_TYPES)})",
            )
        name, value = params.get("name"), params.get("value")
        extra = set(params) - {"name", "value"}
        if extra:
            raise ConfigError.at(
                file, section.line, f"unknown keys in {section.kind}: {sorted(extra)}"
            )
        if not isinstance(name, str) or not name.isidentifier():
            raise ConfigError.at(
                file, section.line_of(("name",)), f"{section.kind} needs a 'name'"
            )
        if name in RESERVED_NAMES:
            raise ConfigError.at(
                file, section.line_of(("name",)), f"'{name}' is reserved"
            )
        if name in self.define_sites:
            raise ConfigError.at(
                file,
                section.line,
                f"'{name}' is defined twice (first at {self.define_sites[name]})",
            )
        given = name in self.overrides
        if given:
            value = self.overrides[name]
        ok, value = check_value(section.name, value)
        if not ok:
            raise ConfigError.at(
                file,
                section.line_of(("value",)),
                f"value of '{name}' must be {describe_type(section.name)}, "
                f"not {value!r}" + (" (given by the caller)" if given else ""),
            )
        self.defines[name] = value
        self.define_sites[name] = f"{file}:{section.line}"

    def block(self, raw: Section) -> None:
        section = substitute_section(raw, self.defines)
        file, line = section.file, section.line
        values = dict(section.params)
        mri = values.pop("mri", None)
        if not isinstance(mri, str) or not mri.strip():
            given = "mri" in section.params
            keys = [] if given else [str(k) for k in values]
            typo = difflib.get_close_matches("mri", keys, n=1)
            hint = f" ('{typo[0]}' may be a typo of it)" if typo else ""
            line_of = section.line_of((typo[0],) if typo else ("mri",))
            raise ConfigError.at(
                file, line_of, f"{section.kind} needs an 'mri' (text){hint}"
            )
        if not MRI.match(mri) or ".." in mri:
            raise ConfigError.at(
                file,
                section.line_of(("mri",)),
                f"{section.kind}: mri {mri!r} may hold only letters, digits and"
                " : _ - . (no spaces, slashes or '..')",
            )
        spec = BlockSpec(section.name, mri, values, file, line, section.param_lines)
        if mri in self.mris:
            first = self.mris[mri]
            raise ConfigError.at(
                file,
                section.line_of(("mri",)),
                f"mri '{mri}' is used twice (first at {first.file}:{first.line})",
            )
        self.mris[mri] = spec
        self.blocks.append(spec)
        definition = self.definition(section)
        if definition is not None:
            resolve_params(
                definition.params,
                values,
                file,
                line=line,
                given_lines=section.param_lines,
                context=section.name,
            )

    def definition(self, section: Section) -> Definition | None:
        path = find_definition(
            section.name, self.search_path, file=section.file, line=section.line
        )
        if path not in self.definitions:
            self.definitions[path] = None
            self.definitions[path] = load_definition(path, name=section.name)
        return self.definitions[path]

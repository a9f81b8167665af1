"""The YAML definition language: sections, parameters, substitution, registry.

See ``docs/config.md`` for the language itself.
"""

from .definitions import (
    ChildBlock,
    ClientRef,
    Definition,
    ExpandedBlock,
    expand,
    find_definition,
    load_definition,
)
from .errors import ConfigError, Problem
from .params import InitParam, resolve_params
from .process_file import BlockSpec, ProcessSpec, expand_process, load_process_file
from .registry import known_kinds, lookup, register
from .yamlsections import Section, load_sections, parse_sections

__all__ = [
    "BlockSpec",
    "ChildBlock",
    "ClientRef",
    "ConfigError",
    "Definition",
    "ExpandedBlock",
    "InitParam",
    "Problem",
    "ProcessSpec",
    "Section",
    "expand",
    "expand_process",
    "find_definition",
    "known_kinds",
    "load_definition",
    "load_process_file",
    "load_sections",
    "lookup",
    "parse_sections",
    "register",
    "resolve_params",
]

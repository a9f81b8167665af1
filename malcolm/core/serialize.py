"""The Malcolm structure both ways, as one import.

- :mod:`malcolm.core.typeids`: ``to_dict``, and ``from_dict`` rebuilding
  objects by ``typeid`` through a registry (``register_typeid``);
- :mod:`malcolm.core.builders`: the builders of the core's own typeids;
- :mod:`malcolm.core.deltas`: ``apply_changes``, applying delta changes to
  plain data as a client does.
"""

from __future__ import annotations

from . import builders as builders  # registers the core's typeids
from .deltas import apply_changes
from .typeids import _REGISTRY as _REGISTRY  # the registry itself (tests restore it)
from .typeids import (
    Builder,
    Path,
    build,
    from_dict,
    located,
    register_typeid,
    registered_typeids,
    to_dict,
    where,
)

__all__ = [
    "Builder",
    "Path",
    "apply_changes",
    "build",
    "from_dict",
    "located",
    "register_typeid",
    "registered_typeids",
    "to_dict",
    "where",
]

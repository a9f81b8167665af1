"""Paths under ``"."``: what the process serves rather than one block.

``[".", "blocks"]`` is an ``NTScalarArray`` of the mris served (its value at
``[".", "blocks", "value"]``, interop.md §3); ``[".", "models", <mri>]`` is
the state machine ``<mri>`` interprets, as plain data (:func:`model_data`),
so that any client can draw it and know which calls each state allows.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from malcolm.core import NotFoundError, Process
from malcolm.fsm import Model

MODEL_TYPEID = "malcolm:fsm/Model:1.0"


def model_data(model: Model) -> dict[str, Any]:
    """A model's states, transitions and call rules as plain data."""
    return {
        "typeid": MODEL_TYPEID,
        "name": model.name,
        "description": model.description,
        "initial": model.initial,
        "states": [
            {
                "name": s.name,
                "busy": s.busy,
                "role": s.role,
                "tags": sorted(s.tags),
                "description": s.description,
            }
            for s in model.states.values()
        ],
        "transitions": [
            {
                "trigger": t.trigger,
                "source": t.source,
                "dest": t.dest,
                "guards": list(t.guards),
                "unless": list(t.unless),
                "phases": list(t.phases),
                "label": t.label(),
            }
            for t in model.transitions
        ],
        "methods": {name: sorted(states) for name, states in model.methods.items()},
        "attributes": {
            name: {"allowed": sorted(rule.allowed), "trigger": rule.trigger}
            for name, rule in model.attributes.items()
        },
    }


def directory_get(process: Process, path: Sequence[str]) -> Any:
    """The data at a path starting ``"."``; ``NotFoundError`` naming it if none."""
    rest = list(path[1:])
    if rest[:1] == ["blocks"]:
        blocks = {
            "typeid": "epics:nt/NTScalarArray:1.0",
            "value": list(process.mris),
        }
        return _index(blocks, rest[1:], path)
    if rest[:1] == ["models"] and len(rest) >= 2:
        model = getattr(process.get_controller(rest[1]), "model", None)
        if not isinstance(model, Model):
            raise NotFoundError(f"block {rest[1]!r} has no model")
        return _index(model_data(model), rest[2:], path)
    raise NotFoundError(
        f"no {'.'.join(path)!r} (under '.' there are: blocks, models.<mri>)"
    )


def _index(data: Any, keys: Sequence[str], path: Sequence[str]) -> Any:
    for key in keys:
        if not isinstance(data, dict) or key not in data:
            raise NotFoundError(f"no {'.'.join(path)!r}")
        data = data[key]
    return data

"""The in-memory form of a state-machine model, as loaded from YAML."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Any

import transitions

# Keys of Model.locations: ("state" | "phase" | "method" | "attribute", name)
# or (top-level key,) such as ("initial",), ("controller",), ("extends",).
Location = tuple[str, int | None]


@dataclass(frozen=True)
class StateInfo:
    """A state; ``busy`` states run phases and are left by ``done``.

    ``role`` is what the state means to a controller (``fault``, ``running``
    ...), unique in a model, so that a model may name its states as it likes;
    ``tags`` are properties several states share (``quiet``).
    """

    name: str
    busy: bool
    description: str
    line: int | None
    file: str = ""
    role: str | None = None
    tags: frozenset[str] = frozenset()


@dataclass(frozen=True)
class PhaseInfo:
    """A phase's ``role`` (unique in a model) and ``tags`` (such as ``long``)."""

    name: str
    role: str | None = None
    tags: frozenset[str] = frozenset()


@dataclass(frozen=True)
class Transition:
    """One move for one source state (lists of sources are expanded)."""

    trigger: str
    source: str
    dest: str
    guards: tuple[str, ...]
    unless: tuple[str, ...]
    phases: tuple[str, ...]
    file: str
    line: int | None

    def label(self) -> str:
        """``trigger [guard, !unless] /Phase,Phase`` for diagrams and messages."""
        text = self.trigger
        conditions = [*self.guards, *(f"!{g}" for g in self.unless)]
        if conditions:
            text += f" [{', '.join(conditions)}]"
        if self.phases:
            text += f" /{','.join(self.phases)}"
        return text

    def __str__(self) -> str:
        return f"{self.trigger} {self.source}->{self.dest}"


@dataclass(frozen=True)
class AttributeRule:
    """Where a put to an attribute is allowed, and the trigger it fires."""

    allowed: frozenset[str]
    trigger: str | None


class Model:
    """A validated state machine: states, phases, transitions and call rules.

    Built by :func:`malcolm.fsm.load_model`; ``parent`` is the model it
    extends (or None) and ``locations`` maps what was declared to its
    ``(file, line)`` so that problems can say where they are.

    A model is read-only once built (its mappings are read-only views, its
    transitions a tuple, and its attributes cannot be set again), so one
    loaded model is shared by every controller that interprets it.
    """

    _frozen = False

    def __init__(
        self,
        *,
        name: str,
        description: str,
        path: Path,
        initial: str,
        controller: str | None,
        states: Mapping[str, StateInfo],
        phases: Mapping[str, str],
        transitions: Sequence[Transition],
        methods: Mapping[str, frozenset[str]],
        attributes: Mapping[str, AttributeRule],
        parent: Model | None = None,
        locations: Mapping[tuple[str, ...], Location] | None = None,
        phase_info: Mapping[str, PhaseInfo] | None = None,
    ) -> None:
        self.name = name
        self.description = description
        self.path = path
        self.initial = initial
        self.controller = controller
        self.states: Mapping[str, StateInfo] = MappingProxyType(dict(states))
        self.phases: Mapping[str, str] = MappingProxyType(dict(phases))
        self.transitions: tuple[Transition, ...] = tuple(transitions)
        self.methods: Mapping[str, frozenset[str]] = MappingProxyType(dict(methods))
        self.attributes: Mapping[str, AttributeRule] = MappingProxyType(
            dict(attributes)
        )
        self.parent = parent
        self.locations: Mapping[tuple[str, ...], Location] = MappingProxyType(
            dict(locations or {})
        )
        #: phase name -> its role and tags (phases without either may be absent)
        self.phase_info: Mapping[str, PhaseInfo] = MappingProxyType(
            {name: (phase_info or {}).get(name) or PhaseInfo(name) for name in phases}
        )
        index: dict[tuple[str, str], list[Transition]] = {}
        for t in self.transitions:
            index.setdefault((t.trigger, t.source), []).append(t)
        self._by_move = {k: tuple(v) for k, v in index.items()}
        self._frozen = True

    def __setattr__(self, name: str, value: Any) -> None:
        if self._frozen:
            raise AttributeError(
                f"model {self.name} is read-only (shared by every controller"
                f" that interprets it): cannot set {name!r}"
            )
        super().__setattr__(name, value)

    def __delattr__(self, name: str) -> None:
        raise AttributeError(f"model {self.name} is read-only: cannot delete {name!r}")

    def __repr__(self) -> str:
        return f"<Model {self.name} from {self.path}>"

    def where(self, *key: str) -> Location:
        """The ``(file, line)`` where ``key`` was declared, else the model file."""
        return self.locations.get(key, (str(self.path), None))

    # Roles and tags ----------------------------------------------------------

    def state_for(self, role: str) -> str:
        """The state with ``role``; KeyError naming the model if none has it."""
        for name, info in self.states.items():
            if info.role == role:
                return name
        raise KeyError(
            f"model {self.name} ({self.path}) has no state with role {role!r}"
        )

    def has_state_role(self, role: str) -> bool:
        return any(info.role == role for info in self.states.values())

    def role_of(self, state: str) -> str | None:
        """The role of ``state`` (None if it has none)."""
        return self.states[state].role

    def is_state(self, state: str, role: str) -> bool:
        """Whether ``state`` is the state with ``role``."""
        info = self.states.get(state)
        return info is not None and info.role == role

    def states_tagged(self, tag: str) -> set[str]:
        return {name for name, info in self.states.items() if tag in info.tags}

    def phase_for(self, role: str) -> str | None:
        """The phase with ``role``, or None if the model has none."""
        for name, info in self.phase_info.items():
            if info.role == role:
                return name
        return None

    def phases_tagged(self, tag: str) -> set[str]:
        return {name for name, info in self.phase_info.items() if tag in info.tags}

    # Queries -----------------------------------------------------------------

    def guards(self) -> set[str]:
        """Every guard name used on a transition, as ``guards`` or ``unless``."""
        return {g for t in self.transitions for g in (*t.guards, *t.unless)}

    def busy_states(self) -> set[str]:
        return {name for name, info in self.states.items() if info.busy}

    def triggers(self) -> set[str]:
        """Every trigger of every transition."""
        return {t.trigger for t in self.transitions}

    def transitions_for(self, trigger: str, source: str) -> list[Transition]:
        """The transitions ``trigger`` may take from ``source``, in order."""
        return list(self._by_move.get((trigger, source), ()))

    def triggers_from(self, source: str) -> set[str]:
        return {t.trigger for t in self.transitions if t.source == source}

    def moves(self) -> dict[str, set[str]]:
        """Source state -> destination states, over all triggers and guards."""
        result: dict[str, set[str]] = {name: set() for name in self.states}
        for t in self.transitions:
            result[t.source].add(t.dest)
        return result

    def allows(self, call: str, state: str) -> bool:
        """Whether method ``call`` may be called in ``state``.

        Only calls listed under ``methods`` are restricted.
        """
        allowed = self.methods.get(call)
        return allowed is None or state in allowed

    def put_allowed(self, attribute: str, state: str) -> bool:
        """Whether ``attribute`` may be put in ``state``.

        Only attributes listed under ``attributes`` are restricted.
        """
        rule = self.attributes.get(attribute)
        return rule is None or state in rule.allowed

    # Machines and pictures ---------------------------------------------------

    def build_machine(self, model_obj: object, **kwargs: Any) -> transitions.Machine:
        """A ``transitions.Machine`` driving ``model_obj``.

        Guards are method names that ``transitions`` looks up on ``model_obj``.
        Phases are not run by the machine: the controller runs them before
        firing the trigger. ``kwargs`` are passed on and override the defaults.
        """
        options: dict[str, Any] = {
            "model": model_obj,
            "states": list(self.states),
            "transitions": [
                {
                    "trigger": t.trigger,
                    "source": t.source,
                    "dest": t.dest,
                    "conditions": list(t.guards),
                    "unless": list(t.unless),
                }
                for t in self.transitions
            ],
            "initial": self.initial,
            "auto_transitions": False,
            "ignore_invalid_triggers": False,
            "send_event": False,
        }
        options.update(kwargs)
        return transitions.Machine(**options)

    def to_mermaid(self) -> str:
        from .draw import to_mermaid

        return to_mermaid(self)

    def to_dot(self) -> str:
        from .draw import to_dot

        return to_dot(self)

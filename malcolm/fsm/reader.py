"""Read one model file's YAML on top of its parent into a Model."""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from malcolm.yamlio import LineDict, LineList

from .errors import Problem
from .model import AttributeRule, Location, Model, PhaseInfo, StateInfo, Transition

TOP_KEYS = (
    "name",
    "description",
    "extends",
    "controller",
    "initial",
    "states",
    "phases",
    "replace_phases",
    "transitions",
    "methods",
    "attributes",
)
STATE_KEYS = ("busy", "description", "role", "tags")
PHASE_KEYS = ("description", "role", "tags")
TRANSITION_KEYS = ("trigger", "source", "dest", "guards", "unless", "phases")
ATTRIBUTE_KEYS = ("allowed", "trigger")

_CONTROLLER = re.compile(r"^[A-Za-z_]\w*(\.[A-Za-z_]\w*)*:[A-Za-z_]\w*$")


def _is_name(value: Any) -> bool:
    return isinstance(value, str) and value.isidentifier()


def _is_camel(value: Any) -> bool:
    return _is_name(value) and value[0].isupper()


def _is_role(value: Any) -> bool:
    """Roles and tags are lower_snake_case identifiers."""
    return _is_name(value) and value == value.lower()


class ModelReader:
    """Turns one file's parsed YAML, on top of the model it extends, into a
    :class:`Model`, appending every problem found to ``problems``."""

    def __init__(self, path: Path, problems: list[Problem]) -> None:
        self.path = path
        self.file = str(path)
        self.problems = problems
        self.locations: dict[tuple[str, ...], Location] = {}

    def problem(self, line: int | None, message: str) -> None:
        self.problems.append(Problem(self.file, line, message))

    def at(self, key: tuple[str, ...], line: int | None) -> None:
        self.locations[key] = (self.file, line)

    # Small typed readers -----------------------------------------------------

    def check_keys(self, mapping: LineDict, allowed: Sequence[str], what: str) -> None:
        for key in mapping:
            if key not in allowed:
                self.problem(
                    mapping.line_of(key),
                    f"unknown key {key!r} in {what} (expected one of "
                    f"{', '.join(allowed)})",
                )

    def mapping(self, data: LineDict, key: str) -> LineDict:
        value = data.get(key)
        if value is None:
            empty = LineDict()
            empty.line = data.line_of(key)
            return empty
        if not isinstance(value, LineDict):
            self.problem(data.line_of(key), f"{key} must be a mapping")
            return LineDict()
        return value

    def text(self, data: LineDict, key: str, what: str) -> str | None:
        value = data.get(key)
        if value is None:
            return None
        if not isinstance(value, str):
            self.problem(data.line_of(key), f"{what} must be a string, not {value!r}")
            return None
        return value

    def names(
        self, value: Any, line: int | None, what: str, camel: bool = False
    ) -> list[tuple[str, int | None]]:
        """A string or list of strings, each a valid name, with its line."""
        if value is None:
            return []
        if isinstance(value, str):
            items = [(value, line)]
        elif isinstance(value, LineList):
            items = [(v, value.line_of(i)) for i, v in enumerate(value)]
        else:
            self.problem(line, f"{what} must be a name or a list of names")
            return []
        good = []
        for item, item_line in items:
            ok = _is_camel(item) if camel else _is_name(item)
            if ok:
                good.append((item, item_line))
            else:
                self.problem(item_line, f"{what} {item!r} is not a valid name")
        return good

    def known_states(
        self, items: list[tuple[str, int | None]], states: dict, where: str
    ) -> list[str]:
        result = []
        for name, line in items:
            if name in states:
                result.append(name)
            else:
                self.problem(line, f"{where}: {name!r} is not a state")
        return result

    # The file ----------------------------------------------------------------

    def check_top(self, data: Any) -> bool:
        """Check what needs no parent; False if ``data`` is not a mapping."""
        if not isinstance(data, LineDict):
            self.problem(None, "a model file must be a mapping")
            return False
        self.check_keys(data, TOP_KEYS, "model")
        if not _is_camel(data.get("name")):
            self.problem(
                data.line_of("name"),
                f"name must be a CamelCase identifier, not {data.get('name')!r}",
            )
        if "extends" not in data and "replace_phases" in data:
            self.problem(
                data.line_of("replace_phases"),
                "replace_phases needs extends: there is nothing to replace",
            )
        return True

    def read(self, data: LineDict, parent: Model | None) -> Model:
        """Merge ``data`` (already passed through :meth:`check_top`) onto
        ``parent``."""
        name = data.get("name")
        if not _is_camel(name):
            name = self.path.stem
        description = self.text(data, "description", "description") or ""
        if parent is not None:
            self.locations.update(parent.locations)

        controller = self.text(data, "controller", "controller")
        if controller is not None:
            self.at(("controller",), data.line_of("controller"))
            if not _CONTROLLER.match(controller):
                self.problem(
                    data.line_of("controller"),
                    f"controller {controller!r} must look like 'package.module:Class'",
                )
        elif parent is not None:
            controller = parent.controller

        states = self.read_states(data, parent)
        phases, replaced = self.read_phases(data, parent)
        self.unique_roles(
            {
                n: (i.role, self.locations.get(("phase", n), (None, None))[1])
                for n, i in self.phase_info.items()
            },
            "phase",
        )
        initial = self.read_initial(data, parent, states)
        transitions = self.inherit_transitions(parent, replaced)
        transitions += self.read_transitions(data, states, phases)
        methods = self.read_methods(data, parent, states)
        attributes = self.read_attributes(data, parent, states)
        return Model(
            name=name,
            description=description,
            path=self.path,
            initial=initial,
            controller=controller,
            states=states,
            phases=phases,
            transitions=transitions,
            methods=methods,
            attributes=attributes,
            parent=parent,
            locations=self.locations,
            phase_info=self.phase_info,
        )

    def read_states(self, data: LineDict, parent: Model | None) -> dict[str, StateInfo]:
        states = dict(parent.states) if parent else {}
        table = self.mapping(data, "states")
        for name, spec in table.items():
            line = table.line_of(name)
            if not _is_camel(name):
                self.problem(line, f"state {name!r} is not a CamelCase name")
                continue
            if spec is None:
                spec = LineDict()
            if not isinstance(spec, LineDict):
                self.problem(
                    line, f"state {name}: must be a mapping {{busy, description}}"
                )
                continue
            self.check_keys(spec, STATE_KEYS, f"state {name}")
            old = states.get(name)
            busy = spec.get("busy", old.busy if old else False)
            if not isinstance(busy, bool):
                self.problem(
                    spec.line_of("busy"), f"state {name}: busy must be true/false"
                )
                busy = False
            description = self.text(spec, "description", f"state {name} description")
            if description is None:
                description = old.description if old else ""
            role, tags = self.role_and_tags(spec, f"state {name}", old)
            states[name] = StateInfo(
                name, busy, description, line, self.file, role, tags
            )
            self.at(("state", name), line)
        if not states:
            self.problem(table.line or data.line, "a model needs at least one state")
        self.unique_roles(
            {
                n: (i.role, self.locations.get(("state", n), (None, None))[1])
                for n, i in states.items()
            },
            "state",
        )
        return states

    def role_and_tags(
        self, spec: LineDict, what: str, old: Any
    ) -> tuple[str | None, frozenset[str]]:
        """A state's or phase's ``role`` and ``tags``; unrestated, the old ones."""
        role = spec.get("role", old.role if old else None)
        if role is not None and not _is_role(role):
            self.problem(
                spec.line_of("role"),
                f"{what}: role must be a lower_snake_case name, not {role!r}",
            )
            role = None
        tags = old.tags if old else frozenset()
        if "tags" in spec:
            found = self.names(spec["tags"], spec.line_of("tags"), f"{what} tag")
            bad = [t for t, _ in found if not _is_role(t)]
            for t in bad:
                self.problem(
                    spec.line_of("tags"),
                    f"{what}: tag {t!r} must be a lower_snake_case name",
                )
            tags = frozenset(t for t, _ in found if t not in bad)
        return role, tags

    def unique_roles(
        self, roles: dict[str, tuple[str | None, int | None]], what: str
    ) -> None:
        seen: dict[str, str] = {}
        for name, (role, line) in roles.items():
            if role is None:
                continue
            if role in seen:
                self.problem(
                    line,
                    f"{what} {name}: role {role!r} is already the role of"
                    f" {what} {seen[role]} (a role names one {what})",
                )
            else:
                seen[role] = name

    def read_phases(
        self, data: LineDict, parent: Model | None
    ) -> tuple[dict[str, str], dict[str, tuple[str, ...]]]:
        phases = dict(parent.phases) if parent else {}
        self.phase_info: dict[str, PhaseInfo] = (
            dict(parent.phase_info) if parent else {}
        )
        table = self.mapping(data, "phases")
        for name, value in table.items():
            line = table.line_of(name)
            if not _is_camel(name):
                self.problem(line, f"phase {name!r} is not a CamelCase name")
                continue
            old = self.phase_info.get(name)
            role, tags = (old.role, old.tags) if old else (None, frozenset())
            if isinstance(value, LineDict):
                self.check_keys(value, PHASE_KEYS, f"phase {name}")
                description = self.text(value, "description", f"phase {name}")
                role, tags = self.role_and_tags(value, f"phase {name}", old)
            elif value is None or isinstance(value, str):
                description = value
            else:
                self.problem(
                    line,
                    f"phase {name}: the value must be a description or a mapping"
                    " {description, role, tags}",
                )
                description = None
            if description is None and name in phases:
                description = phases[name]
            phases[name] = description or ""
            self.phase_info[name] = PhaseInfo(name, role, tags)
            self.at(("phase", name), line)

        replaced: dict[str, tuple[str, ...]] = {}
        if parent is None:
            return phases, replaced
        table = self.mapping(data, "replace_phases")
        for old, new in table.items():
            line = table.line_of(old)
            if old not in parent.phases:
                self.problem(
                    line, f"replace_phases: {old!r} is not a phase of {parent.name}"
                )
                continue
            replaced[old] = tuple(
                n for n, _ in self.names(new, line, "replacement phase", camel=True)
            )
        for old in replaced:
            phases.pop(old, None)
            self.phase_info.pop(old, None)
            self.locations.pop(("phase", old), None)
        for old, new in replaced.items():
            for phase in new:
                if phase not in phases:
                    self.problem(
                        table.line_of(old),
                        f"replace_phases {old}: phase {phase!r} is not declared",
                    )
        return phases, replaced

    def read_initial(
        self, data: LineDict, parent: Model | None, states: dict[str, StateInfo]
    ) -> str:
        initial = data.get("initial")
        if initial is None:
            if parent is not None:
                return parent.initial
            self.problem(data.line, "initial is required in a model that extends none")
            return ""
        line = data.line_of("initial")
        self.at(("initial",), line)
        if initial not in states:
            self.problem(line, f"initial {initial!r} is not a state")
        return str(initial)

    def inherit_transitions(
        self, parent: Model | None, replaced: dict[str, tuple[str, ...]]
    ) -> list[Transition]:
        if parent is None:
            return []
        result = []
        for t in parent.transitions:
            phases = tuple(p for old in t.phases for p in replaced.get(old, (old,)))
            result.append(
                Transition(
                    t.trigger,
                    t.source,
                    t.dest,
                    t.guards,
                    t.unless,
                    phases,
                    t.file,
                    t.line,
                )
            )
        return result

    def read_transitions(
        self, data: LineDict, states: dict[str, StateInfo], phases: dict[str, str]
    ) -> list[Transition]:
        table = data.get("transitions")
        if table is None:
            return []
        if not isinstance(table, LineList):
            self.problem(data.line_of("transitions"), "transitions must be a list")
            return []
        result = []
        for i, spec in enumerate(table):
            line = table.line_of(i)
            if not isinstance(spec, LineDict):
                self.problem(
                    line, "a transition must be a mapping {trigger, source, dest}"
                )
                continue
            result += self.read_transition(spec, line, states, phases)
        return result

    def read_transition(
        self,
        spec: LineDict,
        line: int | None,
        states: dict[str, StateInfo],
        phases: dict[str, str],
    ) -> list[Transition]:
        self.check_keys(spec, TRANSITION_KEYS, "transition")
        ok = True
        trigger = spec.get("trigger")
        if not _is_name(trigger):
            self.problem(line, f"transition trigger must be a name, not {trigger!r}")
            ok = False
        for key in ("source", "dest"):
            if key not in spec:
                self.problem(line, f"transition {trigger}: {key} is missing")
                ok = False
        label = f"transition {trigger}"
        sources = self.names(spec.get("source"), spec.line_of("source"), "source")
        sources_ok = self.known_states(sources, states, f"{label} source")
        dests = self.names(spec.get("dest"), spec.line_of("dest"), "dest")
        if len(dests) > 1:
            self.problem(spec.line_of("dest"), f"{label}: dest must be one state")
        dest_ok = self.known_states(dests[:1], states, f"{label} dest")
        guards = self.names(spec.get("guards"), spec.line_of("guards"), "guard")
        unless = self.names(spec.get("unless"), spec.line_of("unless"), "guard")
        used = self.names(spec.get("phases"), spec.line_of("phases"), "phase", True)
        for phase, phase_line in used:
            if phase not in phases:
                self.problem(
                    phase_line,
                    f"{label}: phase {phase!r} is not declared under phases",
                )
                ok = False
        if not ok or len(sources_ok) != len(sources) or not dest_ok:
            return []
        return [
            Transition(
                trigger=trigger,
                source=source,
                dest=dest_ok[0],
                guards=tuple(g for g, _ in guards),
                unless=tuple(g for g, _ in unless),
                phases=tuple(p for p, _ in used),
                file=self.file,
                line=line,
            )
            for source in sources_ok
        ]

    def read_methods(
        self, data: LineDict, parent: Model | None, states: dict[str, StateInfo]
    ) -> dict[str, frozenset[str]]:
        methods = dict(parent.methods) if parent else {}
        table = self.mapping(data, "methods")
        for name, allowed in table.items():
            line = table.line_of(name)
            if not _is_name(name):
                self.problem(line, f"method {name!r} is not a valid name")
                continue
            found = self.names(allowed, line, f"method {name} state")
            found = self.known_states(found, states, f"method {name}")
            methods[name] = methods.get(name, frozenset()) | frozenset(found)
            self.at(("method", name), line)
        return methods

    def read_attributes(
        self, data: LineDict, parent: Model | None, states: dict[str, StateInfo]
    ) -> dict[str, AttributeRule]:
        attributes = dict(parent.attributes) if parent else {}
        table = self.mapping(data, "attributes")
        for name, spec in table.items():
            line = table.line_of(name)
            if not _is_name(name):
                self.problem(line, f"attribute {name!r} is not a valid name")
                continue
            if not isinstance(spec, LineDict) or "allowed" not in spec:
                self.problem(line, f"attribute {name}: must be {{allowed: [...]}}")
                continue
            self.check_keys(spec, ATTRIBUTE_KEYS, f"attribute {name}")
            found = self.names(spec["allowed"], spec.line_of("allowed"), "state")
            found = self.known_states(found, states, f"attribute {name}")
            trigger = spec.get("trigger")
            if trigger is not None and not _is_name(trigger):
                self.problem(
                    spec.line_of("trigger"),
                    f"attribute {name}: bad trigger {trigger!r}",
                )
                trigger = None
            old = attributes.get(name)
            if old is not None:
                found_set = old.allowed | frozenset(found)
                trigger = trigger if trigger is not None else old.trigger
            else:
                found_set = frozenset(found)
            attributes[name] = AttributeRule(found_set, trigger)
            self.at(("attribute", name), line)
        return attributes

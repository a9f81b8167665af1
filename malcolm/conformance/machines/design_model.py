"""The Editor machine's own model of a manager: what the loaded design
says (exports, followers, fixed values, layout, model name), every child
value, the saved designs and templates, and the state by role; and the
rules by which they change (followers follow, drift faults, a table edit
disables, a load writes the design's values)."""

from __future__ import annotations

import copy
from typing import Any

from malcolm.editor.plan import FIXED_KINDS, plain_value
from malcolm.parts.design import ExportPart, FollowerPart, ModelPart, PalettePart

from ..designs import other_value
from .rigs import Field, Spec, same


class DesignBook:
    """Mixed into the Editor machine: its expectations and how they change."""

    spec: Spec
    values: dict[str, Any]
    fields: dict[str, Field]
    children: list[str]
    saved: dict[str, Spec]
    templates: dict[str, Spec]
    #: the state's role: ready, fault or disabled
    state: str
    #: what drifted when the fault came: name -> (expected, actual)
    faults: dict[str, tuple[Any, Any]]
    modified: bool

    def designs(self) -> dict[str, Spec]:
        return {**self.templates, **self.saved}

    def source_of(self, export: str) -> str:
        return next(src for name, src, _ in self.spec.exports if name == export)

    def source_value(self, source: str) -> Any:
        """The value of the manager attribute a follower follows."""
        if source == "model":  # not an export: the manager's own attribute
            return self.spec.model
        return self.values[self.source_of(source)]

    def follow(self) -> None:
        """Every follower takes its source's value (the manager does this itself)."""
        for target, source in self.spec.followers:
            self.values[target] = copy.deepcopy(self.source_value(source))

    def set_value(self, dotted: str, value: Any) -> None:
        """A child attribute written; followers of an export of it follow."""
        self.values[dotted] = copy.deepcopy(value)
        for target, source in self.spec.followers:
            if source != "model" and self.source_of(source) == dotted:
                self.values[target] = copy.deepcopy(value)

    def drift(self) -> list[str]:
        """Followed and fixed child attributes that differ from the design."""
        out = [d for d, v in self.spec.fixed.items() if not same(self.values[d], v)]
        for target, source in self.spec.followers:
            if not same(self.values[target], self.source_value(source)):
                out.append(target)
        return out

    def after_foreign_write(self) -> None:
        if self.state == "ready":
            drift = self.drift()
            if drift:
                self.state = "fault"
                self.faults = {d: (self.wanted(d), self.values[d]) for d in drift}

    def wanted(self, dotted: str) -> Any:
        """What the design says a fixed or followed child attribute holds."""
        if dotted in self.spec.fixed:
            return self.spec.fixed[dotted]
        source = next(s for t, s in self.spec.followers if t == dotted)
        return self.source_value(source)

    def sources(self) -> set[str]:
        return {src for _, src, _ in self.spec.exports}

    def targets(self) -> set[str]:
        return {target for target, _ in self.spec.followers}

    def install(self, exports: Any = None, followers: Any = None) -> None:
        """A valid table edit: new tables, no longer fixed what moved, disabled."""
        if exports is not None:
            self.spec.exports = exports
        if followers is not None:
            self.spec.followers = followers
        moved = self.sources() | self.targets()
        self.spec.fixed = {d: v for d, v in self.spec.fixed.items() if d not in moved}
        self.follow()
        self.state = "disabled"
        self.modified = True

    def apply(self, spec: Spec) -> None:
        """Load: the design's tables and fixed values, written to the children."""
        self.spec.exports = list(spec.exports)
        self.spec.followers = list(spec.followers)
        self.spec.fixed = copy.deepcopy(spec.fixed)
        self.spec.layout = {c: (0.0, 0.0, True) for c in self.children}
        self.spec.layout.update(spec.layout)
        self.spec.model = spec.model
        for d, v in spec.fixed.items():
            self.set_value(d, v)
        self.follow()

    def expected_records(self, spec: Spec) -> list[Any]:
        records: list[Any] = []
        if spec.model:
            records.append(ModelPart(spec.model))
        for child in self.children:
            x, y, visible = spec.layout[child]
            records.append(PalettePart(child, int(x), int(y), visible))
        records += [ExportPart(n, s, d) for n, s, d in spec.exports]
        records += [FollowerPart(t, s) for t, s in spec.followers]
        for d, v in spec.fixed.items():
            kind = self.fields[d].kind
            records.append(FIXED_KINDS[kind](d, plain_value(v, kind)))
        return records

    def other_spec(self) -> Spec:
        """A design another hand writes: an export, a follower of it if a
        field of the same kind is free, four fixed values, a new layout."""
        fields = list(self.fields.values())
        spec = Spec(model="Other")
        for i, child in enumerate(self.children):
            spec.layout[child] = (float(2 * i + 1), float(2 * i + 2), i % 3 != 2)
        if fields:
            first = fields[0]
            spec.exports.append(("Gate", first.dotted, ""))
            twin = next((f for f in fields[1:] if self.can_follow(f, first)), None)
            if twin is not None:
                spec.followers.append((twin.dotted, "Gate"))
            moved = {first.dotted} | {t for t, _ in spec.followers}
            for f in [f for f in fields if f.dotted not in moved][:4]:
                value = other_value(f.meta, self.values[f.dotted])
                if value is not None:
                    spec.fixed[f.dotted] = f.validate(value)
        return spec

    def can_follow(self, target: Field, source: Field | None) -> bool:
        """The machine's follower rule: the same kind (and table columns); the
        manager's ``model`` (source None) for a string."""
        if source is None:
            return target.kind == "fixed.String"
        if target.kind != source.kind:
            return False
        elements = getattr(target.meta, "elements", None)
        return elements is None or list(elements) == list(source.meta.elements)

    def exportable(self) -> list[str]:
        """Child attributes an export may mirror: not followers' targets."""
        return sorted(set(self.fields) - self.targets())

    def some_field(self) -> Field:
        return next(iter(self.fields.values()))

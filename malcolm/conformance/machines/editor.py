"""A hypothesis state machine driving a LIVE manager and its Editor.

The manager and its children come from a :class:`~.rigs.Rig` (a process
file's blocks with a copy of the designs saved for the manager, or soft
children a test makes). Everything runs in one Process on one asyncio loop
kept for the whole example; each rule is one ``loop.run_until_complete``
that ends once the manager's own background writes (followers following)
have finished.

Rules (the Editor's calls and puts run in the ready state; in every other
state they, reset in ready and disable in disabled must raise
NotAllowedError and change nothing):

* writes to the manager's exported attributes (any state), and writes "by
  someone else" to followed, fixed, exported and free child attributes
  (any state; sometimes the value the design wants, so that no drift
  happens); a value the child refuses changes nothing;
* save under a random name (valid, invalid, empty = the loaded one, and a
  template's name, which is refused), load of every saved name, every
  template and a missing name (by put of ``design`` or by ``load()``), and
  designs written into the store by another hand (then loadable by name);
* reset (from fault and disabled) and disable (from ready and fault);
* edits of the exports, followers, fixed and layout tables, valid ones and
  invalid ones that must be refused with nothing changed.

The machine keeps its own model of what the design says, of every child
value, of the saved designs and of the state (by role), and after every
rule checks that the live manager agrees: it is in the fault state exactly
when a write by someone else made a followed or fixed child attribute
differ from the design while it was ready, with health naming the
attribute, the expected and the actual value; every child value is the
model's (reset and load wrote the design's values back); the tables, the
fixed values, ``design``, ``modified`` and ``model`` are the model's; a
save writes a file that reads back as exactly the records expected.
"""

from __future__ import annotations

import asyncio
import copy
import json
import re
import shutil
import tempfile
from dataclasses import asdict
from pathlib import Path
from typing import Any, ClassVar

import pytest
from hypothesis import strategies as st
from hypothesis.stateful import (
    RuleBasedStateMachine,
    initialize,
    invariant,
    precondition,
    rule,
)

from malcolm.core import BadValueError, NotAllowedError
from malcolm.editor.plan import plain_value
from malcolm.editor.store import DesignStore
from malcolm.parts.design import (
    load_design,
)

from ..designs import mentions
from .design_model import DesignBook
from .rigs import Field, Rig, Spec, same, spec_of

CALL_TIMEOUT = 10.0
NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.\-]*$")
SAVE_NAMES = ("d1", "d2", "v1.2", "Zeta-9", "_bad", "a b", "")
EXPORT_NAMES = ("Arm", "Start", "Width", "Mode", "Label", "Gate", "Seq")
POSITIONS = st.integers(-(10**6), 10**6).map(float)


class EditorMachine(DesignBook, RuleBasedStateMachine):
    """Bound to a rig by :func:`editor_machine_for` (class attribute ``rig``)."""

    rig: ClassVar[Rig]

    def __init__(self) -> None:
        super().__init__()
        self.tmp = Path(tempfile.mkdtemp(prefix="malcolm-editor-machine-"))
        self.loop = asyncio.new_event_loop()
        try:
            self.build_rig()
        except BaseException:
            self.loop.close()
            shutil.rmtree(self.tmp, ignore_errors=True)
            raise

    def build_rig(self) -> None:
        """Build and start the rig; read what the manager starts with."""
        designs = self.tmp / "designs"
        self.rig.seed_designs(designs)
        self.process, self.m = self.rig.build(designs)
        self.mri = self.m.mri
        self.loop.run_until_complete(self.process.start())
        self.fields: dict[str, Field] = self.rig.fields(self.process, self.m)
        self.children = list(self.m.children)
        # the model
        self.state = "ready"
        #: what drifted when the fault came: name -> (expected, actual)
        self.faults: dict[str, tuple[Any, Any]] = {}
        self.values = {d: copy.deepcopy(self.child_value(d)) for d in self.fields}
        self.spec = Spec(layout={c: (0.0, 0.0, True) for c in self.children})
        self.design_name = ""
        self.modified = False
        self.saved: dict[str, Spec] = {}
        self.templates: dict[str, Spec] = {}
        store = self.m.store
        for name in store.names():
            spec = spec_of(load_design(store.path(name)), self.fields, self.children)
            if store.is_template(name):
                self.templates[name] = spec
            else:
                self.saved[name] = spec
        if self.m.design.value:  # loaded at start
            self.apply(self.designs()[self.m.design.value])
            self.design_name = self.m.design.value

    def teardown(self) -> None:
        try:
            self.loop.run_until_complete(self.process.stop())
            pending = asyncio.all_tasks(self.loop)
            for task in pending:
                task.cancel()
            if pending:
                self.loop.run_until_complete(
                    asyncio.gather(*pending, return_exceptions=True)
                )
        finally:
            self.loop.close()
            shutil.rmtree(self.tmp, ignore_errors=True)

    # ---- running things on the loop
    async def _settle(self) -> None:
        """Until the manager's own writes (followers following) are done."""
        for _ in range(1000):
            if not self.m.background:
                await asyncio.sleep(0)
                if not self.m.background:
                    return
            await asyncio.sleep(0)
        raise AssertionError(f"background writes never finished: {self.m.background}")

    def run(self, coro: Any) -> Any:
        async def go() -> Any:
            try:
                return await asyncio.wait_for(coro, CALL_TIMEOUT)
            finally:
                await self._settle()

        return self.loop.run_until_complete(go())

    def refused(self, coro: Any, error: type[Exception]) -> None:
        """The call must raise ``error``; the invariant then checks nothing changed."""
        with pytest.raises(error):
            self.run(coro)

    def accepted(self, coro: Any) -> bool:
        """Run a write; False if the child refused the value (BadValueError)."""
        try:
            self.run(coro)
        except BadValueError:
            return False
        return True

    def put(self, name: str, value: Any) -> Any:
        return self.process.put([self.mri, name], value)

    def post(self, name: str, **params: Any) -> Any:
        return self.process.post([self.mri, name], params)

    def role(self) -> str | None:
        return self.m.model.role_of(self.m.current)

    # ---- the live side
    def child_value(self, dotted: str) -> Any:
        f = self.fields[dotted]
        return self.process.get_block(f.mri)[f.name].value

    def rows(self, attr: Any) -> list[dict[str, Any]]:
        value = attr.value
        cols = list(value)
        n = len(value[cols[0]]) if cols else 0
        return [{c: value[c][i] for c in cols} for i in range(n)]

    def exports_value(self, exports: list[tuple[str, str, str]]) -> dict[str, Any]:
        return {
            "name": [n for n, _, _ in exports],
            "source": [s for _, s, _ in exports],
            "description": [d for _, _, d in exports],
        }

    def followers_value(self, followers: list[tuple[str, str]]) -> dict[str, Any]:
        return {"name": [t for t, _ in followers], "source": [s for _, s in followers]}

    def fixed_value(self, fixed: dict[str, Any]) -> dict[str, Any]:
        """The ``fixed`` table of ``{CHILD.ATTRIBUTE: value}``: values as JSON."""
        return {
            "name": list(fixed),
            "value": [
                json.dumps(plain_value(v, self.fields[d].kind))
                for d, v in fixed.items()
            ],
        }

    def layout_rows(self) -> list[dict[str, Any]]:
        return [
            {"name": c, "mri": self.m.children[c], "x": x, "y": y, "visible": v}
            for c, (x, y, v) in self.spec.layout.items()
        ]

    # ---- rules: initial design
    @initialize(data=st.data())
    def start(self, data: st.DataObject) -> None:
        names = sorted(self.designs())
        if names and data.draw(st.booleans(), "load one first"):
            name = data.draw(st.sampled_from(names), "design")
            self.run(self.put("design", name))
            self.apply(self.designs()[name])
            self.design_name = name
            self.modified = False

    # ---- rules: writes
    @precondition(lambda self: bool(self.spec.exports))
    @rule(data=st.data())
    def write_export(self, data: st.DataObject) -> None:
        """A client writes an exported attribute of the manager (any state)."""
        name, source, _ = data.draw(st.sampled_from(self.spec.exports), "export")
        value = data.draw(self.fields[source].values(), "value")
        if self.accepted(self.put(name, value)):
            self.set_value(source, self.fields[source].validate(value))
            self.after_foreign_write()

    @precondition(lambda self: bool(self.fields))
    @rule(data=st.data())
    def write_child(self, data: st.DataObject) -> None:
        """Someone else writes a child attribute (followed, fixed, exported, free)."""
        groups = {
            "followed": sorted(self.targets()),
            "fixed": sorted(self.spec.fixed),
            "exported": sorted(self.sources()),
            "free": sorted(
                set(self.fields)
                - self.targets()
                - set(self.spec.fixed)
                - self.sources()
            ),
        }
        group = data.draw(st.sampled_from([g for g, ds in groups.items() if ds]))
        dotted = data.draw(st.sampled_from(groups[group]), "attribute")
        if group == "fixed":
            wanted = self.spec.fixed[dotted]
        elif group == "followed":
            source = next(s for t, s in self.spec.followers if t == dotted)
            wanted = self.source_value(source)
        else:
            wanted = self.values[dotted]
        f = self.fields[dotted]
        value = data.draw(
            st.one_of(st.just(copy.deepcopy(wanted)), f.values()), "value"
        )
        if not self.accepted(self.process.put([f.mri, f.name], value)):
            return
        self.set_value(dotted, f.validate(value))
        self.after_foreign_write()
        if self.state == "fault" and data.draw(st.booleans(), "then reset"):
            self.agrees_with_the_model()
            self.reset()

    # ---- rules: lifecycle
    @precondition(lambda self: self.state in ("fault", "disabled"))
    @rule()
    def reset(self) -> None:
        """Reset writes the fixed and followed values back and returns to ready."""
        self.run(self.post("reset"))
        for d, v in self.spec.fixed.items():
            self.set_value(d, v)
        self.follow()
        self.state = "ready"
        self.faults = {}

    @precondition(lambda self: self.state in ("ready", "fault"))
    @rule()
    def disable(self) -> None:
        self.run(self.post("disable"))
        self.state = "disabled"

    @rule()
    def lifecycle_refused(self) -> None:
        """Reset is refused in ready, disable in disabled."""
        if self.state == "ready":
            self.refused(self.post("reset"), NotAllowedError)
        elif self.state == "disabled":
            self.refused(self.post("disable"), NotAllowedError)

    # ---- rules: save and load
    @precondition(lambda self: self.state == "ready")
    @rule(data=st.data())
    def save(self, data: st.DataObject) -> None:
        name = data.draw(st.sampled_from([*SAVE_NAMES, *self.templates]), "name")
        target = name or self.design_name
        if not NAME.match(target) or target in self.templates:
            self.refused(self.post("save", design=name), BadValueError)
            return
        self.run(self.post("save", design=name))
        moved = self.sources() | self.targets()
        self.spec.fixed = {
            d: copy.deepcopy(self.values[d]) for d in self.fields if d not in moved
        }
        self.saved[target] = copy.deepcopy(self.spec)
        self.design_name = target
        self.modified = False
        assert target in self.m.design.meta.choices
        # the file reads back as exactly what the model expects
        path = self.m.store.dir / f"{target}.yaml"
        loaded = [(type(r), asdict(r)) for r in load_design(path).records]
        expected = [(type(r), asdict(r)) for r in self.expected_records(self.spec)]
        assert same(loaded, expected), (loaded, expected)

    @rule(name=st.sampled_from(["d2", "other", "v1.2"]))
    def another_hand_saves(self, name: str) -> None:
        """A design file written by another hand can be loaded (any state)."""
        if name in self.templates:
            return
        spec = self.other_spec()
        store = DesignStore(self.mri, self.tmp / "designs")
        store.save(name, self.expected_records(spec))
        self.saved[name] = spec

    @precondition(lambda self: self.state == "ready")
    @rule(data=st.data(), by_put=st.booleans())
    def load(self, data: st.DataObject, by_put: bool) -> None:
        name = data.draw(st.sampled_from([*sorted(self.designs()), "missing"]))
        call = self.put("design", name) if by_put else self.post("load", design=name)
        if name == "missing":
            self.refused(call, BadValueError)
            return
        self.run(call)
        self.apply(self.designs()[name])
        self.design_name = name
        self.modified = False

    # ---- rules: table edits
    @precondition(lambda self: self.state == "ready" and bool(self.fields))
    @rule(data=st.data(), as_rows=st.booleans(), then_reset=st.booleans())
    def edit_exports(
        self, data: st.DataObject, as_rows: bool, then_reset: bool
    ) -> None:
        exports = list(self.spec.exports)
        followed = {s for _, s in self.spec.followers}
        free_names = [n for n in EXPORT_NAMES if n not in {e[0] for e in exports}]
        edits = ["describe", "shuffle"]
        if free_names and self.exportable():
            edits.append("add")
        if any(e[0] not in followed for e in exports):
            edits.append("remove")
        if exports:
            edits.append("resource")
        edit = data.draw(st.sampled_from(edits), "edit")
        if edit == "add":
            name = data.draw(st.sampled_from(free_names), "name")
            source = data.draw(st.sampled_from(self.exportable()), "source")
            at = data.draw(st.integers(0, len(exports)), "at")
            exports.insert(at, (name, source, data.draw(st.sampled_from(["", "d"]))))
        elif edit == "remove":
            gone = data.draw(
                st.sampled_from([e for e in exports if e[0] not in followed])
            )
            exports.remove(gone)
        elif edit == "resource":
            i = data.draw(st.integers(0, len(exports) - 1), "row")
            name, old, description = exports[i]
            choices = [
                d
                for d in self.exportable()
                if name not in followed
                or self.can_follow(self.fields[d], self.fields[old])
            ]
            exports[i] = (name, data.draw(st.sampled_from(choices)), description)
        elif edit == "describe" and exports:
            i = data.draw(st.integers(0, len(exports) - 1), "row")
            name, source, _ = exports[i]
            exports[i] = (name, source, data.draw(st.text(max_size=8)))
        elif edit == "shuffle":
            exports = data.draw(st.permutations(exports))
        value = self.exports_value(exports)
        if as_rows:
            value = [dict(zip(value, row)) for row in zip(*value.values())]
        self.run(self.put("exports", value))
        self.install(exports=exports)
        if then_reset:
            self.reset()

    @precondition(lambda self: self.state == "ready" and bool(self.fields))
    @rule(data=st.data())
    def edit_exports_invalid(self, data: st.DataObject) -> None:
        exports = list(self.spec.exports)
        followed = {s for _, s in self.spec.followers}
        f = self.some_field()
        child = f.dotted.partition(".")[0]
        bad = [
            ("Gx", f"NOPE.{f.name}"),  # no such child
            ("Gx", f"{child}.NOPE"),  # no such attribute
            ("Gx", child),  # not CHILD.FIELD
            ("design", f.dotted),  # a field of the manager
            ("1x", f.dotted),  # not an identifier
        ]
        if exports:
            bad.append((exports[0][0], f.dotted))  # twice the same name
        if self.spec.followers:  # an attribute a follower sets
            bad.append(("Gx", self.spec.followers[0][0]))
        orphans = followed & {e[0] for e in exports}
        choice = data.draw(st.sampled_from([*bad, None] if orphans else bad))
        if choice is None:  # drop an export a follower follows
            exports = [e for e in exports if e[0] not in followed]
        else:
            exports.append((*choice, ""))
        self.refused(self.put("exports", self.exports_value(exports)), BadValueError)

    @precondition(lambda self: self.state == "ready" and bool(self.fields))
    @rule(data=st.data(), then_reset=st.booleans())
    def edit_followers(self, data: st.DataObject, then_reset: bool) -> None:
        followers = list(self.spec.followers)
        sources: dict[str, Field | None] = {
            name: self.fields[src] for name, src, _ in self.spec.exports
        }
        sources["model"] = None  # a manager attribute that is not an export
        free = sorted(set(self.fields) - self.sources() - self.targets())
        candidates = [
            (d, name)
            for d in free
            for name, source in sources.items()
            if self.can_follow(self.fields[d], source)
        ]
        edits = ["shuffle"]
        if candidates:
            edits.append("add")
        if followers:
            edits += ["remove", "resource"]
        edit = data.draw(st.sampled_from(edits), "edit")
        if edit == "add":
            at = data.draw(st.integers(0, len(followers)), "at")
            followers.insert(at, data.draw(st.sampled_from(candidates), "follower"))
        elif edit == "remove":
            followers.pop(data.draw(st.integers(0, len(followers) - 1), "row"))
        elif edit == "resource":
            i = data.draw(st.integers(0, len(followers) - 1), "row")
            target = followers[i][0]
            alike = [
                n for n, s in sources.items() if self.can_follow(self.fields[target], s)
            ]
            followers[i] = (target, data.draw(st.sampled_from(alike), "source"))
        else:
            followers = data.draw(st.permutations(followers))
        self.run(self.put("followers", self.followers_value(followers)))
        self.install(followers=followers)
        if then_reset:
            self.reset()

    @precondition(lambda self: self.state == "ready" and bool(self.fields))
    @rule(data=st.data())
    def edit_followers_invalid(self, data: st.DataObject) -> None:
        followers = list(self.spec.followers)
        source = self.spec.exports[0][0] if self.spec.exports else "health"
        f = self.some_field()
        child = f.dotted.partition(".")[0]
        bad = [
            (f"NOPE.{f.name}", source),  # no such child
            (f"{child}.NOPE", source),  # no such attribute
            (child, source),  # not CHILD.FIELD
            (f.dotted, "Nope"),  # not a field of the manager
        ]
        if followers:
            bad.append(followers[0])  # the same target twice
        if self.spec.exports:  # an attribute an export writes
            name, exported, _ = self.spec.exports[0]
            bad.append((exported, name))
        followers.append(data.draw(st.sampled_from(bad)))
        self.refused(
            self.put("followers", self.followers_value(followers)), BadValueError
        )

    def draw_fixed_value(self, data: st.DataObject, dotted: str) -> Any:
        """A value the child accepts, as its meta holds it."""
        f = self.fields[dotted]
        for _ in range(20):
            try:
                return f.validate(data.draw(f.values(), "value"))
            except (BadValueError, TypeError, ValueError):
                continue
        return copy.deepcopy(self.values[dotted])

    @precondition(lambda self: self.state == "ready" and bool(self.fields))
    @rule(data=st.data(), then_reset=st.booleans())
    def edit_fixed(self, data: st.DataObject, then_reset: bool) -> None:
        """A put of ``fixed``: a row added, dropped, given another value, or
        the rows reordered; written to the children on reset."""
        fixed = dict(self.spec.fixed)
        free = sorted(set(self.fields) - self.sources() - self.targets() - set(fixed))
        edits = ["shuffle"]
        if free:
            edits.append("add")
        if fixed:
            edits += ["remove", "revalue"]
        edit = data.draw(st.sampled_from(edits), "edit")
        if edit == "add":
            dotted = data.draw(st.sampled_from(free), "attribute")
            fixed[dotted] = self.draw_fixed_value(data, dotted)
        elif edit == "remove":
            fixed.pop(data.draw(st.sampled_from(sorted(fixed)), "row"))
        elif edit == "revalue":
            dotted = data.draw(st.sampled_from(sorted(fixed)), "row")
            fixed[dotted] = self.draw_fixed_value(data, dotted)
        else:
            order = data.draw(st.permutations(list(fixed)), "order")
            fixed = {d: fixed[d] for d in order}
        self.run(self.put("fixed", self.fixed_value(fixed)))
        self.spec.fixed = fixed
        self.install()
        if then_reset:
            self.reset()

    @precondition(lambda self: self.state == "ready" and bool(self.fields))
    @rule(data=st.data())
    def edit_fixed_invalid(self, data: st.DataObject) -> None:
        value = self.fixed_value(self.spec.fixed)
        f = self.some_field()
        child = f.dotted.partition(".")[0]
        text = json.dumps(plain_value(self.values[f.dotted], f.kind))
        bad = [
            (f"NOPE.{f.name}", text),  # no such child
            (f"{child}.NOPE", text),  # no such attribute
            (child, text),  # not CHILD.FIELD
            (f.dotted, "{not json"),  # not JSON
        ]
        if self.spec.fixed:  # the same attribute twice
            bad.append((value["name"][0], value["value"][0]))
        moving = sorted(self.sources() | self.targets())
        if moving:  # exported or followed
            d = moving[0]
            bad.append(
                (d, json.dumps(plain_value(self.values[d], self.fields[d].kind)))
            )
        name, text = data.draw(st.sampled_from(bad), "row")
        value = {"name": [*value["name"], name], "value": [*value["value"], text]}
        self.refused(self.put("fixed", value), BadValueError)

    @precondition(lambda self: self.state == "ready" and bool(self.children))
    @rule(data=st.data(), visible=st.booleans(), by_put=st.booleans())
    def set_visible(self, data: st.DataObject, visible: bool, by_put: bool) -> None:
        child = data.draw(st.sampled_from(self.children), "child")
        then_reset = data.draw(st.booleans(), "then reset")
        x, y, was = self.spec.layout[child]
        if by_put:
            rows = self.layout_rows()
            rows[self.children.index(child)]["visible"] = visible
            call = self.put("layout", rows)
        else:
            call = self.post("set_visible", block_name=child, visible=visible)
        self.run(call)
        self.spec.layout[child] = (x, y, visible)
        self.modified = True
        if visible != was:
            self.install()
            if then_reset:
                self.reset()

    @precondition(lambda self: self.state == "ready" and bool(self.children))
    @rule(data=st.data(), x=POSITIONS, y=POSITIONS, by_put=st.booleans())
    def set_position(
        self, data: st.DataObject, x: float, y: float, by_put: bool
    ) -> None:
        child = data.draw(st.sampled_from(self.children), "child")
        if by_put:
            rows = self.layout_rows()
            rows[self.children.index(child)].update(x=x, y=y)
            call = self.put("layout", rows)
        else:
            call = self.post("set_position", block_name=child, x=x, y=y)
        self.run(call)
        self.spec.layout[child] = (x, y, self.spec.layout[child][2])
        self.modified = True

    @precondition(lambda self: self.state == "ready" and len(self.children) > 1)
    @rule(data=st.data())
    def edit_layout_invalid(self, data: st.DataObject) -> None:
        rows = self.layout_rows()
        child = self.children[-1]
        how = data.draw(
            st.sampled_from(
                ["visible", "position", "nan", "inf", "rename", "mri", "reorder"]
            )
        )
        if how == "visible":
            call = self.post("set_visible", block_name="NOPE", visible=False)
        elif how == "position":
            call = self.post("set_position", block_name="NOPE", x=1.0, y=2.0)
        elif how in ("nan", "inf"):
            bad = float("nan") if how == "nan" else -float("inf")
            call = self.post("set_position", block_name=child, x=bad, y=3.0)
        elif how == "rename":
            rows[0]["name"] = "NOPE"
            call = self.put("layout", rows)
        elif how == "mri":
            rows[1]["mri"] = f"{self.mri}:NOPE"
            call = self.put("layout", rows)
        else:
            call = self.put("layout", rows[::-1])
        self.refused(call, BadValueError)

    @precondition(lambda self: self.state != "ready")
    @rule(data=st.data())
    def only_in_ready(self, data: st.DataObject) -> None:
        """Every call and put of the Editor is refused outside ready."""
        names = sorted(self.designs()) or ["d1"]
        child = self.children[0] if self.children else "NOPE"
        calls = {
            "save": lambda: self.post("save", design="d1"),
            "load": lambda: self.post("load", design=data.draw(st.sampled_from(names))),
            "put design": lambda: self.put("design", data.draw(st.sampled_from(names))),
            "exports": lambda: self.put(
                "exports", self.exports_value(self.spec.exports)
            ),
            "followers": lambda: self.put(
                "followers", self.followers_value(self.spec.followers)
            ),
            "fixed": lambda: self.put("fixed", self.fixed_value(self.spec.fixed)),
            "layout": lambda: self.put("layout", self.layout_rows()),
            "set_visible": lambda: self.post(
                "set_visible", block_name=child, visible=False
            ),
            "set_position": lambda: self.post(
                "set_position", block_name=child, x=1.0, y=1.0
            ),
        }
        call = data.draw(st.sampled_from(sorted(calls)), "call")
        self.refused(calls[call](), NotAllowedError)

    # ---- the checks
    @invariant()
    def agrees_with_the_model(self) -> None:
        m = self.m
        assert self.role() == self.state, (m.current, self.state, m.health.value)
        drift = self.drift()
        health = m.health.value
        if self.state == "ready":
            assert not drift, f"Ready, but {drift} differ from the design"
            assert health == "OK", health
        if self.state == "fault":
            named = [n for n in self.faults if n in health]
            assert named, (sorted(self.faults), health)
            want, have = self.faults[named[0]]
            assert mentions(health, want) and mentions(health, have), (
                f"health {health!r} must name the expected value {want!r} and"
                f" the actual value {have!r} of {named[0]}"
            )
        for dotted in self.fields:
            actual = self.child_value(dotted)
            assert same(actual, self.values[dotted]), (dotted, actual, self.values)
        assert self.rows(m.exports) == [
            {"name": n, "source": s, "description": d} for n, s, d in self.spec.exports
        ]
        assert self.rows(m.followers) == [
            {"name": t, "source": s} for t, s in self.spec.followers
        ]
        assert self.rows(m.layout) == self.layout_rows()
        fixed = {r.name: self.fields[r.name].validate(r.value) for r in m.fixed_records}
        assert fixed.keys() == self.spec.fixed.keys(), (fixed, self.spec.fixed)
        for d, v in fixed.items():
            assert same(v, self.spec.fixed[d]), (d, v, self.spec.fixed[d])
        # the fixed table shows the same rows, values as JSON text
        table = self.rows(m.fixed)
        assert [r["name"] for r in table] == list(fixed), (table, list(fixed))
        for r in table:
            shown = self.fields[r["name"]].validate(json.loads(r["value"]))
            assert same(shown, self.spec.fixed[r["name"]]), (r, self.spec.fixed)
        for name, source, _ in self.spec.exports:
            assert same(m.block[name].value, self.values[source]), name
        assert m.design.value == self.design_name
        assert m.modified.value == self.modified
        assert m.model_attr.value == self.spec.model
        templates = [n for n in self.templates if n not in self.saved]
        assert m.store.names() == [*sorted(self.saved), *templates]
        litter = [p.name for p in m.store.dir.glob("*") if not p.suffix == ".yaml"]
        assert not litter, litter


def editor_machine_for(rig: Rig) -> type[EditorMachine]:
    """The Editor machine bound to ``rig``."""
    return type(f"EditorMachineFor{type(rig).__name__}", (EditorMachine,), {"rig": rig})

"""A hypothesis state machine driving a LIVE ManagerController and its Editor.

The manager ``Z`` manages four soft children (``Z:PCOMP1``, ``Z:PCOMP2``,
``Z:PCAP``, ``Z:SEQ1``) whose writeable attributes cover every ``fixed.*``
kind (float, int, bool, enum, string, table). The design document's example
design (``PositionBased.yaml``) is a read-only template called ``example``.
Everything runs in one Process on one asyncio loop kept for the whole
example; each rule is one ``loop.run_until_complete`` that ends once the
manager's own background writes (followers following) have finished.

Rules (the Editor's calls and puts run in Ready; in every other state they,
reset in Ready and disable in Disabled must raise NotAllowedError and change
nothing):

* writes to the manager's exported attributes (any state), and writes "by
  someone else" to followed, fixed, exported and free child attributes (any
  state; sometimes the value the design wants, so that no drift happens);
* save under a random name (valid, invalid, empty = the loaded one, and the
  template's name, which is refused), load of every saved name, the example
  and a missing name (by put of ``design`` or by ``load()``), and designs
  written into the store by another hand (then loadable by name);
* reset (from Fault and Disabled) and disable (from Ready and Fault);
* edits of the exports, followers and layout tables (put of the tables,
  ``set_visible``, ``set_position``), valid ones (a follower follows an
  export of the same type or the manager's own ``model``; an edit may export
  or follow a fixed attribute, which unfixes it) and invalid ones (missing
  child, missing attribute, not CHILD.FIELD, taken or bad export names, a
  follower left without its export, a duplicated follower, an attribute
  both exported and followed, unknown blocks,
  renamed rows, non-finite positions) that must be refused with nothing
  changed.

The test keeps its own model of what the design says (exports, followers,
fixed values, layout, model name), of every child value, of the saved
designs and of the state, and after every rule checks that the live
manager agrees with it:

* the state is the model's; the manager is in Fault exactly when a write by
  someone else made a followed or fixed child attribute differ from what the
  design says while the manager was Ready (drift is NOT checked in Disabled
  and Disabling, nor in Fault, Resetting, Saving and Loading: the
  states tagged ``quiet`` in the model), and health names the attribute; in Ready there
  is never any drift;
* every child value is the model's (so the manager wrote exactly what the
  design says and nothing else: reset from Fault or Disabled writes the
  fixed and followed values back, a followed attribute follows its export);
* the exports, followers and layout tables, the fixed values, ``design``,
  ``modified`` and ``model`` are the model's, and every export mirrors its
  child attribute;
* a save writes a file that ``load_design`` reads back as exactly the
  records the model expects, leaves no temporary file, and the name appears
  in the ``design`` choices; load of a saved name reproduces every fixed value
  and every table saved under it.

Positions are whole numbers: a design stores ``xcoord``/``ycoord`` as ints,
so a fractional position does not survive a save and load.
"""

from __future__ import annotations

import asyncio
import copy
import math
import re
import shutil
import tempfile
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st
from hypothesis.stateful import (
    RuleBasedStateMachine,
    initialize,
    invariant,
    precondition,
    rule,
)

from malcolm.controllers.manager import ManagerController
from malcolm.controllers.stateful import StatefulController
from malcolm.core import (
    BadValueError,
    BooleanMeta,
    ChoiceMeta,
    NotAllowedError,
    NumberArrayMeta,
    NumberMeta,
    Process,
    StringMeta,
    TableMeta,
)
from malcolm.editor.store import DesignStore
from malcolm.fsm import load_model
from malcolm.parts import ChildPart, Part
from malcolm.parts.design import (
    ExportPart,
    FixedBool,
    FixedEnum,
    FixedFloat,
    FixedInt,
    FixedString,
    FixedTable,
    FollowerPart,
    ModelPart,
    PalettePart,
    load_design,
)

EXAMPLE_FILE = (
    Path(__file__).parent.parent
    / "unit"
    / "config_fixtures"
    / "designs"
    / "PositionBased.yaml"
)
MRI = "Z"
#: read once: every example builds five controllers
STATEFUL, MANAGER = load_model("stateful"), load_model("manager")
CALL_TIMEOUT = 10.0
NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.\-]*$")

# --------------------------------------------------------------------------
# The children: soft blocks whose attributes are all writeable

MODES = ("edge", "level", "pulse")
COLUMNS = ("Phase1Time", "Phase2Time", "NRepeats")
INT32 = st.integers(-(2**31), 2**31 - 1)


def _table_meta() -> TableMeta:
    return TableMeta({c: NumberArrayMeta("int32") for c in COLUMNS})


def _table(rows: list[dict[str, int]]) -> dict[str, tuple[int, ...]]:
    return {c: tuple(r[c] for r in rows) for c in COLUMNS}


#: kind -> (meta factory, initial value, values, the fixed record class)
KINDS: dict[str, tuple[Any, Any, st.SearchStrategy[Any], type]] = {
    "float": (
        lambda: NumberMeta("float64"),
        0.0,
        st.one_of(
            st.sampled_from([0.0, 1.5, -2.0, 5.0]),
            st.integers(-(10**6), 10**6).map(float),
            st.floats(),  # NaN and infinities too
        ),
        FixedFloat,
    ),
    "int": (
        lambda: NumberMeta("int32"),
        0,
        st.one_of(st.sampled_from([0, 1, 32, -7]), INT32),
        FixedInt,
    ),
    "bool": (BooleanMeta, False, st.booleans(), FixedBool),
    "choice": (lambda: ChoiceMeta(MODES), MODES[0], st.sampled_from(MODES), FixedEnum),
    "string": (
        StringMeta,
        "",
        st.one_of(st.sampled_from(["", "x", "yes", "1"]), st.text(max_size=12)),
        FixedString,
    ),
    "table": (
        _table_meta,
        _table([]),
        st.lists(st.fixed_dictionaries({c: INT32 for c in COLUMNS}), max_size=3).map(
            _table
        ),
        FixedTable,
    ),
}

CHILDREN: dict[str, list[tuple[str, str]]] = {
    "PCOMP1": [("START", "float"), ("WIDTH", "int")],
    "PCOMP2": [("START", "float"), ("WIDTH", "int")],
    "PCAP": [("START", "float"), ("ARM", "bool"), ("MODE", "choice")],
    "SEQ1": [("TABLE", "table"), ("LABEL", "string")],
}
#: CHILD.FIELD -> kind, in the order a save writes the fixed records
FIELDS: dict[str, str] = {
    f"{child}.{name}": kind for child, fs in CHILDREN.items() for name, kind in fs
}
EXPORT_NAMES = ("Arm", "Start", "Width", "Mode", "Label", "Gate", "Seq")


class Soft(Part):
    """A child's writeable attributes, nothing else."""

    def __init__(self, name: str, fields: list[tuple[str, str]]) -> None:
        super().__init__(name)
        self.fields = fields

    def setup(self, registrar: Any) -> None:
        for name, kind in self.fields:
            make, initial = KINDS[kind][0], KINDS[kind][1]
            meta = make()
            meta.writeable = True
            registrar.add_attribute(name, meta, copy.deepcopy(initial))


def same(a: Any, b: Any) -> bool:
    """The test's own equality: lists and tuples alike, NaN equal to NaN."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if isinstance(a, list | tuple) and isinstance(b, list | tuple):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    if isinstance(a, bool) or isinstance(b, bool):
        return type(a) is type(b) and a == b
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a):
        return math.isnan(b)
    return type(a) is type(b) and a == b


def plain_rows(table: dict[str, tuple[int, ...]]) -> list[dict[str, int]]:
    n = len(table[COLUMNS[0]])
    return [{c: table[c][i] for c in COLUMNS} for i in range(n)]


# --------------------------------------------------------------------------
# What a design says, in the test's own terms


@dataclass
class Spec:
    exports: list[tuple[str, str, str]] = field(default_factory=list)
    followers: list[tuple[str, str]] = field(default_factory=list)
    fixed: dict[str, Any] = field(default_factory=dict)
    #: child -> (x, y, visible); a design may name only some children
    layout: dict[str, tuple[float, float, bool]] = field(default_factory=dict)
    model: str = ""


EXAMPLE = Spec(
    exports=[
        ("Arm", "PCAP.START", "Start the experiment"),
        ("Start", "PCOMP1.START", ""),
    ],
    followers=[("PCOMP2.START", "Start")],
    fixed={
        "PCOMP2.WIDTH": 32,
        "SEQ1.TABLE": _table(
            [
                {"Phase1Time": 32, "Phase2Time": 45, "NRepeats": 3},
                {"Phase1Time": 3, "Phase2Time": 5, "NRepeats": 1},
            ]
        ),
    },
    layout={
        "PCOMP1": (12.0, 15.0, True),
        "PCOMP2": (0.0, 0.0, False),
        "PCAP": (200.0, 230.0, True),
    },
    model="PositionBased",
)

#: a design saved by another hand (every child in the palette, a new model)
OTHER = Spec(
    exports=[("Gate", "PCAP.START", ""), ("Seq", "SEQ1.TABLE", "the table")],
    followers=[("PCOMP1.START", "Gate")],
    fixed={
        "PCOMP1.WIDTH": -3,
        "PCAP.ARM": True,
        "PCAP.MODE": "pulse",
        "SEQ1.LABEL": "from a file",
    },
    layout={
        "PCOMP1": (1.0, 2.0, True),
        "PCOMP2": (3.0, 4.0, True),
        "PCAP": (5.0, 6.0, False),
        "SEQ1": (7.0, 8.0, True),
    },
    model="Other",
)
SAVE_NAMES = ("d1", "d2", "v1.2", "Zeta-9", "_bad", "a b", "", "example")
POSITIONS = st.integers(-(10**6), 10**6).map(float)


# --------------------------------------------------------------------------
# The machine


class ManagerMachine(RuleBasedStateMachine):
    def __init__(self) -> None:
        super().__init__()
        self.tmp = Path(tempfile.mkdtemp(prefix="manager-machine-"))
        templates = self.tmp / "templates"
        templates.mkdir()
        shutil.copy(EXAMPLE_FILE, templates / "example.yaml")
        self.loop = asyncio.new_event_loop()
        self.process = Process("test")
        for child, fields in CHILDREN.items():
            self.process.add_controller(
                StatefulController(
                    f"{MRI}:{child}", [Soft("soft", fields)], model=STATEFUL
                )
            )
        self.m = ManagerController(
            MRI,
            [ChildPart(child, f"{MRI}:{child}") for child in CHILDREN],
            designs_dir=self.tmp / "designs",
            template_dirs=[templates],
            model=MANAGER,
        )
        self.process.add_controller(self.m)
        self.loop.run_until_complete(self.process.start())
        # the model
        self.state = "Ready"
        self.fault_names: list[str] = []
        self.values = {d: copy.deepcopy(KINDS[k][1]) for d, k in FIELDS.items()}
        self.spec = Spec(layout={c: (0.0, 0.0, True) for c in CHILDREN})
        self.design_name = ""
        self.modified = False
        self.saved: dict[str, Spec] = {}

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
            op = self.m._op
            if not self.m.background and (op is None or op.done()):
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

    def put(self, name: str, value: Any) -> Any:
        return self.process.put([MRI, name], value)

    def post(self, name: str, **params: Any) -> Any:
        return self.process.post([MRI, name], params)

    # ---- the model's rules
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
        if self.state == "Ready":
            drift = self.drift()
            if drift:
                self.state = "Fault"
                self.fault_names = drift

    def sources(self) -> set[str]:
        return {src for _, src, _ in self.spec.exports}

    def targets(self) -> set[str]:
        return {target for target, _ in self.spec.followers}

    def install(self, exports: Any = None, followers: Any = None) -> None:
        """A valid table edit: new tables, no longer fixed what moved, Disabled."""
        if exports is not None:
            self.spec.exports = exports
        if followers is not None:
            self.spec.followers = followers
        moved = self.sources() | self.targets()
        self.spec.fixed = {d: v for d, v in self.spec.fixed.items() if d not in moved}
        self.follow()
        self.state = "Disabled"
        self.modified = True

    def apply(self, spec: Spec) -> None:
        """Load: the design's tables and fixed values, written to the children."""
        self.spec.exports = list(spec.exports)
        self.spec.followers = list(spec.followers)
        self.spec.fixed = copy.deepcopy(spec.fixed)
        # a child the design's palette leaves out goes back where it starts
        self.spec.layout = {c: (0.0, 0.0, True) for c in CHILDREN}
        self.spec.layout.update(spec.layout)
        self.spec.model = spec.model
        for d, v in spec.fixed.items():
            self.set_value(d, v)
        self.follow()

    def expected_records(self, spec: Spec) -> list[Any]:
        records: list[Any] = []
        if spec.model:
            records.append(ModelPart(spec.model))
        for child in CHILDREN:
            x, y, visible = spec.layout[child]
            records.append(PalettePart(child, int(x), int(y), visible))
        records += [ExportPart(n, s, d) for n, s, d in spec.exports]
        records += [FollowerPart(t, s) for t, s in spec.followers]
        for d, v in spec.fixed.items():
            cls = KINDS[FIELDS[d]][3]
            records.append(cls(d, plain_rows(v) if cls is FixedTable else v))
        return records

    # ---- the live side
    def child_value(self, dotted: str) -> Any:
        child, _, name = dotted.partition(".")
        return self.process.get_block(f"{MRI}:{child}")[name].value

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

    def layout_rows(self) -> list[dict[str, Any]]:
        return [
            {"name": c, "mri": f"{MRI}:{c}", "x": x, "y": y, "visible": v}
            for c, (x, y, v) in self.spec.layout.items()
        ]

    # ---- rules: initial design
    @initialize(load_example=st.booleans())
    def start(self, load_example: bool) -> None:
        if load_example:
            self.run(self.put("design", "example"))
            self.apply(EXAMPLE)
            self.design_name = "example"

    # ---- rules: writes
    @precondition(lambda self: bool(self.spec.exports))
    @rule(data=st.data())
    def write_export(self, data: st.DataObject) -> None:
        """A client writes an exported attribute of the manager (any state)."""
        name, source, _ = data.draw(st.sampled_from(self.spec.exports), "export")
        value = data.draw(KINDS[FIELDS[source]][2], "value")
        self.run(self.put(name, value))
        self.set_value(source, value)
        self.after_foreign_write()

    @rule(data=st.data())
    def write_child(self, data: st.DataObject) -> None:
        """Someone else writes a child attribute (followed, fixed, exported, free)."""
        groups = {
            "followed": sorted(self.targets()),
            "fixed": sorted(self.spec.fixed),
            "exported": sorted(self.sources()),
            "free": sorted(
                set(FIELDS) - self.targets() - set(self.spec.fixed) - self.sources()
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
        value = data.draw(
            st.one_of(st.just(copy.deepcopy(wanted)), KINDS[FIELDS[dotted]][2]),
            "value",
        )
        child, _, attr = dotted.partition(".")
        self.run(self.process.put([f"{MRI}:{child}", attr], value))
        self.set_value(dotted, value)
        self.after_foreign_write()
        if self.state == "Fault" and data.draw(st.booleans(), "then reset"):
            self.agrees_with_the_model()
            self.reset()

    # ---- rules: lifecycle
    @precondition(lambda self: self.state in ("Fault", "Disabled"))
    @rule()
    def reset(self) -> None:
        """Reset writes the fixed and followed values back and returns to Ready."""
        self.run(self.post("reset"))
        for d, v in self.spec.fixed.items():
            self.set_value(d, v)
        self.follow()
        self.state = "Ready"
        self.fault_names = []

    @precondition(lambda self: self.state in ("Ready", "Fault"))
    @rule()
    def disable(self) -> None:
        self.run(self.post("disable"))
        self.state = "Disabled"

    @rule()
    def lifecycle_refused(self) -> None:
        """Reset is refused in Ready, disable in Disabled."""
        if self.state == "Ready":
            self.refused(self.post("reset"), NotAllowedError)
        elif self.state == "Disabled":
            self.refused(self.post("disable"), NotAllowedError)

    # ---- rules: save and load
    @precondition(lambda self: self.state == "Ready")
    @rule(name=st.sampled_from(SAVE_NAMES))
    def save(self, name: str) -> None:
        target = name or self.design_name
        if not NAME.match(target) or target == "example":
            self.refused(self.post("save", design=name), BadValueError)
            return
        self.run(self.post("save", design=name))
        moved = self.sources() | self.targets()
        self.spec.fixed = {
            d: copy.deepcopy(self.values[d]) for d in FIELDS if d not in moved
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
        spec = copy.deepcopy(OTHER)
        store = DesignStore(MRI, self.tmp / "designs")
        store.save(name, self.expected_records(spec))
        self.saved[name] = spec

    @precondition(lambda self: self.state == "Ready")
    @rule(data=st.data(), by_put=st.booleans())
    def load(self, data: st.DataObject, by_put: bool) -> None:
        name = data.draw(
            st.sampled_from([*sorted(self.saved), "example", "missing"]), "design"
        )
        call = self.put("design", name) if by_put else self.post("load", design=name)
        if name == "missing":
            self.refused(call, BadValueError)
            return
        self.run(call)
        self.apply(self.saved.get(name, EXAMPLE))
        self.design_name = name
        self.modified = False

    # ---- rules: table edits
    def exportable(self) -> list[str]:
        """Child attributes an export may mirror: not followers' targets."""
        return sorted(set(FIELDS) - self.targets())

    @precondition(lambda self: self.state == "Ready")
    @rule(data=st.data(), as_rows=st.booleans(), then_reset=st.booleans())
    def edit_exports(
        self, data: st.DataObject, as_rows: bool, then_reset: bool
    ) -> None:
        exports = list(self.spec.exports)
        followed = {s for _, s in self.spec.followers}
        free_names = [n for n in EXPORT_NAMES if n not in {e[0] for e in exports}]
        edits = ["describe", "shuffle"]
        if free_names:
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
                if name not in followed or FIELDS[d] == FIELDS[old]
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

    @precondition(lambda self: self.state == "Ready")
    @rule(data=st.data())
    def edit_exports_invalid(self, data: st.DataObject) -> None:
        exports = list(self.spec.exports)
        followed = {s for _, s in self.spec.followers}
        bad = [
            ("Gx", "NOPE.START"),  # no such child
            ("Gx", "PCOMP1.NOPE"),  # no such attribute
            ("Gx", "PCOMP1"),  # not CHILD.FIELD
            ("design", "PCOMP1.START"),  # a field of the manager
            ("1x", "PCOMP1.START"),  # not an identifier
        ]
        if exports:
            bad.append((exports[0][0], "PCOMP1.START"))  # twice the same name
        if self.spec.followers:  # an attribute a follower sets
            bad.append(("Gx", self.spec.followers[0][0]))
        orphans = followed & {e[0] for e in exports}
        choice = data.draw(st.sampled_from([*bad, None] if orphans else bad))
        if choice is None:  # drop an export a follower follows
            exports = [e for e in exports if e[0] not in followed]
        else:
            exports.append((*choice, ""))
        self.refused(self.put("exports", self.exports_value(exports)), BadValueError)

    @precondition(lambda self: self.state == "Ready")
    @rule(data=st.data(), then_reset=st.booleans())
    def edit_followers(self, data: st.DataObject, then_reset: bool) -> None:
        followers = list(self.spec.followers)
        kinds = {name: FIELDS[src] for name, src, _ in self.spec.exports}
        kinds["model"] = "string"  # a manager attribute that is not an export
        candidates = [
            (d, name)
            for d in sorted(set(FIELDS) - self.sources() - self.targets())
            for name, kind in kinds.items()
            if FIELDS[d] == kind
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
            same_kind = [n for n, k in kinds.items() if k == FIELDS[target]]
            followers[i] = (target, data.draw(st.sampled_from(same_kind), "source"))
        else:
            followers = data.draw(st.permutations(followers))
        value = self.followers_value(followers)
        self.run(self.put("followers", value))
        self.install(followers=followers)
        if then_reset:
            self.reset()

    @precondition(lambda self: self.state == "Ready")
    @rule(data=st.data())
    def edit_followers_invalid(self, data: st.DataObject) -> None:
        followers = list(self.spec.followers)
        source = self.spec.exports[0][0] if self.spec.exports else "health"
        bad = [
            ("NOPE.START", source),  # no such child
            ("PCOMP1.NOPE", source),  # no such attribute
            ("PCOMP1", source),  # not CHILD.FIELD
            ("PCAP.MODE", "Nope"),  # not a field of the manager
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

    @precondition(lambda self: self.state == "Ready")
    @rule(
        child=st.sampled_from(list(CHILDREN)),
        visible=st.booleans(),
        by_put=st.booleans(),
        then_reset=st.booleans(),
    )
    def set_visible(
        self, child: str, visible: bool, by_put: bool, then_reset: bool
    ) -> None:
        x, y, was = self.spec.layout[child]
        if by_put:
            rows = self.layout_rows()
            rows[list(CHILDREN).index(child)]["visible"] = visible
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

    @precondition(lambda self: self.state == "Ready")
    @rule(
        child=st.sampled_from(list(CHILDREN)),
        x=POSITIONS,
        y=POSITIONS,
        by_put=st.booleans(),
    )
    def set_position(self, child: str, x: float, y: float, by_put: bool) -> None:
        if by_put:
            rows = self.layout_rows()
            rows[list(CHILDREN).index(child)].update(x=x, y=y)
            call = self.put("layout", rows)
        else:
            call = self.post("set_position", block_name=child, x=x, y=y)
        self.run(call)
        self.spec.layout[child] = (x, y, self.spec.layout[child][2])
        self.modified = True

    @precondition(lambda self: self.state == "Ready")
    @rule(data=st.data())
    def edit_layout_invalid(self, data: st.DataObject) -> None:
        rows = self.layout_rows()
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
            bad = math.nan if how == "nan" else -math.inf
            call = self.post("set_position", block_name="PCAP", x=bad, y=3.0)
        elif how == "rename":
            rows[0]["name"] = "NOPE"
            call = self.put("layout", rows)
        elif how == "mri":
            rows[1]["mri"] = "Z:NOPE"
            call = self.put("layout", rows)
        else:
            call = self.put("layout", rows[::-1])
        self.refused(call, BadValueError)

    @precondition(lambda self: self.state != "Ready")
    @rule(data=st.data())
    def only_in_ready(self, data: st.DataObject) -> None:
        """Every call and put of the Editor is refused outside Ready."""
        names = [*sorted(self.saved), "example"]
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
            "layout": lambda: self.put("layout", self.layout_rows()),
            "set_visible": lambda: self.post(
                "set_visible", block_name="PCAP", visible=False
            ),
            "set_position": lambda: self.post(
                "set_position", block_name="PCAP", x=1.0, y=1.0
            ),
        }
        call = data.draw(st.sampled_from(sorted(calls)), "call")
        self.refused(calls[call](), NotAllowedError)

    # ---- the checks
    @invariant()
    def agrees_with_the_model(self) -> None:
        m = self.m
        assert m.current == self.state, (m.current, self.state, m.health.value)
        drift = self.drift()
        if self.state == "Ready":
            assert not drift, f"Ready, but {drift} differ from the design"
            assert m.health.value == "OK", m.health.value
        if self.state == "Fault":
            assert any(n in m.health.value for n in self.fault_names), (
                self.fault_names,
                m.health.value,
            )
        for dotted in FIELDS:
            actual = self.child_value(dotted)
            assert same(actual, self.values[dotted]), (dotted, actual, self.values)
        assert self.rows(m.exports) == [
            {"name": n, "source": s, "description": d} for n, s, d in self.spec.exports
        ]
        assert self.rows(m.followers) == [
            {"name": t, "source": s} for t, s in self.spec.followers
        ]
        assert self.rows(m.layout) == self.layout_rows()
        fixed = {
            r.name: _table(r.value) if isinstance(r, FixedTable) else r.value
            for r in m.fixed_records
        }
        assert fixed.keys() == self.spec.fixed.keys(), (fixed, self.spec.fixed)
        for d, v in fixed.items():
            assert same(v, self.spec.fixed[d]), (d, v, self.spec.fixed[d])
        for name, source, _ in self.spec.exports:
            assert same(m.block[name].value, self.values[source]), name
        assert m.design.value == self.design_name
        assert m.modified.value == self.modified
        assert m.model_attr.value == self.spec.model
        assert m.store.names() == [*sorted(self.saved), "example"]
        litter = [p.name for p in m.store.dir.glob("*") if not p.suffix == ".yaml"]
        assert not litter, litter


ManagerMachine.TestCase.settings = settings(
    max_examples=50,
    stateful_step_count=25,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
TestManagerMachine = ManagerMachine.TestCase

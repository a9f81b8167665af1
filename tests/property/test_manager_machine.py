"""The Editor machine (malcolm.conformance.machines.editor) drives a LIVE
manager: on soft children whose writeable attributes cover every
``fixed.*`` kind (float, int, bool, enum, string, table) with the design
document's example design (``PositionBased.yaml``) as a read-only template;
and on every manager of each design source (the builtin Zebra2 process with
the repository's designs, and every --malcolm-designs process file) with a
copy of the designs saved for it."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, settings
from hypothesis.stateful import run_state_machine_as_test

from malcolm.config import ConfigError
from malcolm.conformance.designs import DesignRig
from malcolm.conformance.machines.editor import editor_machine_for
from malcolm.conformance.machines.rigs import ProcessRig, Rig
from malcolm.conformance.options import DesignSource
from malcolm.controllers.manager import ManagerController
from malcolm.controllers.stateful import StatefulController
from malcolm.core import (
    BooleanMeta,
    ChoiceMeta,
    NumberArrayMeta,
    NumberMeta,
    Process,
    StringMeta,
    TableMeta,
)
from malcolm.fsm import load_model
from malcolm.parts import ChildPart, Part

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
COLUMNS = ("Phase1Time", "Phase2Time", "NRepeats")
#: kind -> (meta factory, initial value)
KINDS: dict[str, tuple[Any, Any]] = {
    "float": (lambda: NumberMeta("float64"), 0.0),
    "int": (lambda: NumberMeta("int32"), 0),
    "bool": (BooleanMeta, False),
    "choice": (lambda: ChoiceMeta(("edge", "level", "pulse")), "edge"),
    "string": (StringMeta, ""),
    "table": (
        lambda: TableMeta({c: NumberArrayMeta("int32") for c in COLUMNS}),
        {c: () for c in COLUMNS},
    ),
}
CHILDREN: dict[str, list[tuple[str, str]]] = {
    "PCOMP1": [("START", "float"), ("WIDTH", "int")],
    "PCOMP2": [("START", "float"), ("WIDTH", "int")],
    "PCAP": [("START", "float"), ("ARM", "bool"), ("MODE", "choice")],
    "SEQ1": [("TABLE", "table"), ("LABEL", "string")],
}


def machine_settings(examples: int) -> settings:
    return settings(
        max_examples=examples,
        stateful_step_count=25,
        deadline=None,
        suppress_health_check=[HealthCheck.too_slow],
    )


class Soft(Part):
    """A child's writeable attributes, nothing else."""

    def __init__(self, name: str, fields: list[tuple[str, str]]) -> None:
        super().__init__(name)
        self.fields = fields

    def setup(self, registrar: Any) -> None:
        for name, kind in self.fields:
            make, initial = KINDS[kind]
            meta = make()
            meta.writeable = True
            registrar.add_attribute(name, meta, copy.deepcopy(initial))


class SoftRig(Rig):
    """Manager ``Z`` over soft children ``Z:PCOMP1`` ... with the design
    document's example as the template ``example``."""

    mri = MRI

    def build(self, designs_dir: Path) -> tuple[Process, Any]:
        templates = designs_dir.parent / "templates"
        templates.mkdir(parents=True, exist_ok=True)
        (templates / "example.yaml").write_text(EXAMPLE_FILE.read_text())
        process = Process("test")
        for child, fields in CHILDREN.items():
            process.add_controller(
                StatefulController(
                    f"{MRI}:{child}", [Soft("soft", fields)], model=STATEFUL
                )
            )
        manager = ManagerController(
            MRI,
            [ChildPart(child, f"{MRI}:{child}") for child in CHILDREN],
            designs_dir=designs_dir,
            template_dirs=[templates],
            model=MANAGER,
        )
        process.add_controller(manager)
        return process, manager


def test_editor_machine_on_soft_children() -> None:
    run_state_machine_as_test(
        editor_machine_for(SoftRig()), settings=machine_settings(50)
    )


def managers_of(source: DesignSource) -> list[str]:
    try:
        rig = DesignRig(source.process, source.designs_dir, source.search_path)
    except ConfigError as e:
        pytest.fail(str(e), pytrace=False)
    try:
        return [m.mri for m in rig.managers]
    finally:
        rig.close()


def test_editor_machine_on_designs(design_source: DesignSource) -> None:
    source = design_source
    mris = managers_of(source)
    if not mris:
        pytest.fail(f"{source.process}: builds no manager", pytrace=False)
    for mri in mris:
        rig = ProcessRig(source.process, mri, source.designs_dir, source.search_path)
        run_state_machine_as_test(
            editor_machine_for(rig), settings=machine_settings(20)
        )

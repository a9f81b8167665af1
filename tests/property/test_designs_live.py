"""Every design of every manager a process file builds (the builtin Zebra2
example with the repository's designs, and every --malcolm-designs process
file) is loaded into a live manager and checked row by row
(malcolm.conformance.designs): each Fixed and Follower child attribute holds
what the design says; a change of one by someone else sends the manager to
Fault with health naming the attribute, the expected and the actual value;
reset writes the design's value back. Then the same for the design as the
manager saves it (a Fixed row for every other writeable child attribute)."""

from __future__ import annotations

import pytest

from malcolm.config import ConfigError
from malcolm.conformance.designs import DesignRig, design_problems
from malcolm.conformance.options import DesignSource


def test_designs_hold_and_are_restored(design_source: DesignSource) -> None:
    source = design_source
    try:
        rig = DesignRig(source.process, source.designs_dir, source.search_path)
    except ConfigError as e:
        pytest.fail(str(e), pytrace=False)
    problems: list[str] = []
    try:
        if not rig.managers:
            pytest.fail(f"{source.process}: builds no manager", pytrace=False)
        for manager in rig.managers:
            names = rig.design_names(manager)
            if not names:
                problems.append(
                    f"{source.process}: manager {manager.mri} has no designs"
                    f" (looked in {rig.origins_of(manager)})"
                )
            for name in names:
                problems += design_problems(rig, manager, name)
    finally:
        rig.close()
    assert not problems, "\n".join(problems)

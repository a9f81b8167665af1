"""Seeded defect: reset does not write the Fixed rows' values back (seam:
malcolm.editor.runtime.FixedRuntime.apply, which reset uses; load still
writes them)."""

from malcolm.editor.runtime import FixedRuntime
from tests.seeded import replace_everywhere

original = FixedRuntime.apply


async def apply(self):
    manager = self.manager
    if manager.model.role_of(manager.current) == "resetting":
        return
    await original(self)


replace_everywhere(original, apply)

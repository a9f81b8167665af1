"""Seeded defect: a scan's progress is taken from the fastest part instead
of the slowest (seam: malcolm.controllers.runnable.overall_progress once it
exists; until then RunnableController._on_progress, which takes the min)."""

import malcolm.controllers.runnable as runnable
from tests.seeded import replace_everywhere

if hasattr(runnable, "overall_progress"):

    def overall_progress(steps):
        return max(steps.values())

    replace_everywhere(runnable.overall_progress, overall_progress)
else:
    original = runnable.RunnableController._on_progress

    def _on_progress(self, part, steps):
        if part not in self._progress or self.model.role_of(self.current) != "running":
            return original(self, part, steps)
        self._progress[part] = steps
        done = max(self._progress.values())
        if self.completed.value < done <= self.configured.value:
            self.completed.set_value(done)

    replace_everywhere(original, _on_progress)

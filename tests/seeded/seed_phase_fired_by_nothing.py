"""Seeded defect: the runnable model's Pause phase moves onto the seek
transitions; seek from PostRun is fired by nothing (no put of completedSteps
is allowed there), so a phase sits on a transition nothing fires."""

from tests.seeded import seed_models

seed_models(
    {
        "runnable_device.yaml": (
            "{trigger: seek, source: [Armed, Paused, PostRun], dest: Seeking}",
            "{trigger: seek, source: [Armed, Paused, PostRun], dest: Seeking,"
            " phases: [Pause]}",
        )
    }
)

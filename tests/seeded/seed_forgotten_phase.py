"""Seeded defect: the transition from Seeking back to Armed forgets its Seek
phase (Seek is still on the other moves out of Seeking, so no design rule
notices: only the phase reference table does)."""

from tests.seeded import seed_models

seed_models(
    {
        "runnable_device.yaml": (
            "{trigger: done, source: Seeking, dest: Armed, phases: [Seek]}",
            "{trigger: done, source: Seeking, dest: Armed}",
        )
    }
)

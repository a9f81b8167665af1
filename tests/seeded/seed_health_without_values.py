"""Seeded defect: a Fault from a drifted Fixed or Follower row names the
attribute but not the expected and actual values (seam: FixedRuntime.mismatch
and FollowerRuntime.mismatch, whose text goes into health)."""

from malcolm.editor.runtime import FixedRuntime, FollowerRuntime
from tests.seeded import replace_everywhere

for cls in (FixedRuntime, FollowerRuntime):
    original = cls.mismatch

    def mismatch(self, original=original):
        return None if original(self) is None else f"{self.target} has drifted"

    replace_everywhere(original, mismatch)

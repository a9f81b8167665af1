"""Hook phases: the concurrent phase runner and the Task API parts use."""

from .blocking import BlockingTask
from .runner import Hook, PhaseError, run_phase
from .task import Task, target_path
from .views import BlockView, FieldView

__all__ = [
    "BlockView",
    "BlockingTask",
    "FieldView",
    "Hook",
    "PhaseError",
    "Task",
    "run_phase",
    "target_path",
]

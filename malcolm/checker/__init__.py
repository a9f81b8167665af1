"""``malcolm check``: find every problem in definitions, process files,
saved designs and state-machine models, without starting anything and
without running any code but malcolm's own (a user's classes are imported
and inspected, never called).

The kind of a file is decided by its content (:mod:`.kinds`); each kind is
loaded with its own loader and checked more deeply (:mod:`.checks`). Every
problem is a :class:`Finding` that prints as ``file:line: message`` (or
``file: message`` when no line applies); :func:`run_check` prints them
(:mod:`.report`). Checking never raises: anything unexpected becomes an
``internal error`` finding.
"""

from .checks import check_file, check_files
from .files import default_search_path, expand_files
from .findings import CheckResult, Finding
from .kinds import KINDS, detect_kind
from .report import run_check

__all__ = [
    "KINDS",
    "CheckResult",
    "Finding",
    "check_file",
    "check_files",
    "default_search_path",
    "detect_kind",
    "expand_files",
    "run_check",
]

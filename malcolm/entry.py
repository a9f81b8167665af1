"""The ``malcolm`` script and ``python -m malcolm``.

Kept to one import of ``sys`` so that Ctrl-C while the command line itself
is being imported is reported as one line, like Ctrl-C anywhere else in a
command (``malcolm.cli.main``), not as a traceback.
"""

import sys


def main() -> int:
    """Import and run the command line; 130 if interrupted while importing."""
    try:
        from malcolm.cli import main as run
    except KeyboardInterrupt:
        sys.stderr.write("malcolm: interrupted\n")
        return 130
    return run()

"""``python -m malcolm``: the same as the ``malcolm`` command."""

from malcolm.cli import main

raise SystemExit(main())

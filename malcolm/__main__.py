"""``python -m malcolm``: the same as the ``malcolm`` command."""

from malcolm.entry import main

raise SystemExit(main())

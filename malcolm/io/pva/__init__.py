"""pvAccess for malcolm (interop.md §2), on p4p.

- :mod:`malcolm.io.pva.convert`: Malcolm structures <-> p4p ``Value``s;
- :mod:`malcolm.io.pva.server`: serve every block of a process
  (:func:`start_pva_server`).

See docs/pva.md.
"""

from .server import PvaServer, start_pva_server

__all__ = ["PvaServer", "start_pva_server"]

"""pvAccess for malcolm (interop.md §2), on p4p.

- :mod:`malcolm.io.pva.convert`: Malcolm structures <-> p4p ``Value``s;
- :mod:`malcolm.io.pva.server`: serve every block of a process
  (:func:`start_pva_server`); each served name is a
  :mod:`malcolm.io.pva.channel`, its puts and calls
  :mod:`malcolm.io.pva.channel_requests`.

See docs/pva.md.
"""

from .p4p_import import import_p4p

import_p4p()  # before any module here imports p4p: without setuptools

from .server import PvaServer, start_pva_server  # noqa: E402

__all__ = ["PvaServer", "start_pva_server"]

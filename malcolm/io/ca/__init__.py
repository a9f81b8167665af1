"""Channel Access channels through pyepics (docs/ca.md).

Importing this package registers the ``pyepics`` backend of transport
``ca`` as its default, if pyepics can be imported; ``malcolm.io`` imports it,
so a process's ``ca.*`` attributes talk to real IOCs unless configuration
chooses another backend (``MALCOLM_CA_BACKEND=soft``, docs/channels.md).
pyepics itself (and libca) is loaded when the first channel is made.
"""

from __future__ import annotations

import importlib.util

from ..backends import register_backend
from ..channel import Backend

__all__ = ["AVAILABLE", "make_backend"]

#: whether pyepics can be imported here
AVAILABLE = importlib.util.find_spec("epics") is not None


def make_backend() -> Backend:
    """A new :class:`~.backend.PyepicsBackend` (imports pyepics)."""
    from .backend import PyepicsBackend

    return PyepicsBackend()


if AVAILABLE:
    register_backend("ca", "pyepics", make_backend, default=True)

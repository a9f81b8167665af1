"""Which backend makes a process's channels, per transport.

A backend is registered under a transport (``"ca"``, ``"pva"``,
``"zebra2"``) and a name. Each process uses one backend per transport,
chosen in this order:

1. one given to :func:`use_backend` (an object, or a registered name);
2. ``Process(channels={"ca": "soft"})``;
3. the environment variable ``MALCOLM_<TRANSPORT>_BACKEND``
   (``MALCOLM_CA_BACKEND=soft``);
4. the transport's default: ``soft`` unless a real adapter registered
   itself as the default (``ca``: pyepics, :mod:`malcolm.io.ca`).

``soft`` (:class:`~malcolm.io.soft.SoftBackend`) is registered for every
transport. The backend object is made the first time a part asks
(:func:`backend_for`) and kept on the process until it stops.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import TYPE_CHECKING

from .channel import Backend
from .soft import SoftBackend

if TYPE_CHECKING:
    from malcolm.core import Process

__all__ = ["backend_for", "backend_names", "register_backend", "use_backend"]

Factory = Callable[[], Backend]

#: (transport, name) -> what makes the backend; "soft" serves every transport
_FACTORIES: dict[tuple[str, str], Factory] = {}
_DEFAULTS: dict[str, str] = {}
SOFT = "soft"


def register_backend(
    transport: str, name: str, factory: Factory, default: bool = False
) -> None:
    """Register ``factory`` as backend ``name`` of ``transport``.

    With ``default`` it becomes what processes use unless told otherwise.
    """
    _FACTORIES[(transport, name)] = factory
    if default:
        _DEFAULTS[transport] = name


def backend_names(transport: str) -> list[str]:
    """The backends a process may choose for ``transport``."""
    names = [n for (t, n) in _FACTORIES if t == transport]
    return names if SOFT in names else [SOFT, *names]


def _make(transport: str, name: str, where: str) -> Backend:
    factory = _FACTORIES.get((transport, name))
    if factory is None and name == SOFT:
        factory = SoftBackend
    if factory is None:
        known = ", ".join(backend_names(transport))
        raise ValueError(
            f"{where}: no {transport!r} channel backend called {name!r}"
            f" (there are: {known})"
        )
    return factory()


def backend_for(process: Process, transport: str) -> Backend:
    """The backend making ``transport`` channels for ``process``."""
    backend = process.backends.get(transport)
    if backend is not None:
        return backend
    variable = f"MALCOLM_{transport.upper()}_BACKEND"
    if transport in process.channels:
        name, where = process.channels[transport], f"process {process.name!r}"
    elif os.environ.get(variable):
        name, where = os.environ[variable], variable
    else:
        name, where = _DEFAULTS.get(transport, SOFT), "default"
    backend = process.backends[transport] = _make(transport, name.strip(), where)
    return backend


def use_backend(process: Process, transport: str, backend: Backend | str) -> Backend:
    """Make ``process`` use ``backend`` (an object or a registered name) for
    ``transport`` from now on; returns it."""
    if isinstance(backend, str):
        backend = _make(transport, backend, f"process {process.name!r}")
    process.backends[transport] = backend
    return backend

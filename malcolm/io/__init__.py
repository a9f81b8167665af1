"""Transports: the channel protocol and the backends that implement it.

See docs/channels.md. ``malcolm.io.channel`` is the protocol,
``malcolm.io.soft`` the in-memory backend, ``malcolm.io.backends`` how a
process chooses a backend per transport.
"""

from . import ca  # noqa: E402,F401  (registers the pyepics backend of "ca")
from .backends import backend_for, backend_names, register_backend, use_backend
from .channel import (
    Backend,
    Channel,
    ChannelClosedError,
    ChannelError,
    ChannelInfo,
    ChannelTimeoutError,
    ConnectionState,
    DisconnectedError,
    Reading,
)
from .soft import SoftBackend, SoftChannel, SoftRecord

__all__ = [
    "Backend",
    "Channel",
    "ChannelClosedError",
    "ChannelError",
    "ChannelInfo",
    "ChannelTimeoutError",
    "ConnectionState",
    "DisconnectedError",
    "Reading",
    "SoftBackend",
    "SoftChannel",
    "SoftRecord",
    "backend_for",
    "backend_names",
    "register_backend",
    "use_backend",
]

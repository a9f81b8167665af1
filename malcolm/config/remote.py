"""``client.X`` sections whose ``fullname`` names a block in another process.

``fullname: pva://HOST[:PORT]/MRI`` (port 5075 if not given) makes the
client's part control a local block at ``MRI`` that mirrors the block
``MRI`` served at ``HOST:PORT`` over pvAccess
(:class:`malcolm.io.pva.client.RemoteBlock`, docs/pva-client.md); a plain
fullname is the mri of a block of the same process, as before. p4p is only
imported when such a block is made.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

__all__ = ["SCHEME", "RemoteName", "make_remote_block", "parse_remote"]

SCHEME = "pva://"
DEFAULT_PORT = 5075


@dataclass(frozen=True)
class RemoteName:
    """A parsed ``pva://HOST:PORT/MRI``."""

    host: str
    port: int
    mri: str

    @property
    def address(self) -> str:
        return f"{self.host}:{self.port}"

    def __str__(self) -> str:
        return f"{SCHEME}{self.address}/{self.mri}"


def parse_remote(fullname: str) -> RemoteName | None:
    """The remote block a fullname names, None for a plain mri; ValueError
    saying what is wrong with a malformed ``pva://`` name."""
    if not isinstance(fullname, str) or "://" not in fullname:
        return None
    scheme, _, rest = fullname.partition("://")
    if f"{scheme}://" != SCHEME:
        raise ValueError(
            f"fullname {fullname!r}: unknown transport {scheme!r} (use {SCHEME}"
            "HOST:PORT/MRI, or a plain mri for a block of this process)"
        )
    address, slash, mri = rest.partition("/")
    if not slash or not mri:
        raise ValueError(f"fullname {fullname!r} names no block: {SCHEME}HOST:PORT/MRI")
    host, colon, port = address.rpartition(":")
    if not colon:
        host, port = port, str(DEFAULT_PORT)
    if not host:
        raise ValueError(f"fullname {fullname!r} names no host")
    if not port.isdigit() or not 0 < int(port) < 65536:
        raise ValueError(f"fullname {fullname!r}: port {port!r} is not a port number")
    return RemoteName(host, int(port), mri)


def make_remote_block(mri: str, address: str) -> Any:
    """The local block mirroring ``mri`` at ``address`` (made when built)."""
    from malcolm.io.pva.client import RemoteBlock

    return RemoteBlock(mri, address)

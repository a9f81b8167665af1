"""Client of a block served by another process over pvAccess.

A :class:`RemoteBlock` is what a process hosts for a ``client.X`` section
whose ``fullname`` is ``pva://HOST[:PORT]/MRI`` (docs/pva-client.md): a local
block at ``MRI`` that mirrors the remote one. The process uses it as it
uses a controller (``mri``, ``block``, ``health``, ``start``, ``stop``,
``put``, ``call``), so parts, views and managers use it like a local block.

- **Structure and values**: one pvAccess monitor of channel ``MRI`` (the
  ``pva`` channel backend, :mod:`.client_channel`). The first update after
  every (re)connection is the whole block: every field is built from it
  (:func:`malcolm.core.from_dict`: metas, typeids, methods' takes and
  defaults), fields the server no longer has are removed; later updates
  change only the fields they name: a value, alarm and timeStamp are set
  (one delta), a method's ``writeable``, ``took`` and ``returned`` follow,
  a changed meta replaces the field.
- **Puts and calls** go to the server (a put to ``MRI.field``, an RPC on
  ``MRI.method``) and are awaited; the server's error
  ``"<ExceptionType>: <message>"`` is re-raised here as that exception with
  that message (:func:`~.client_convert.remote_error`).
- **A lost server**: every attribute's alarm becomes INVALID
  (``CLIENT_STATUS``, naming the address), ``health`` says
  ``pva://HOST:PORT/MRI: connection lost``, every method becomes
  not writeable, and puts and calls raise DisconnectedError. p4p searches
  on; when the server is back the whole block is read again: values,
  alarms and health are the server's, with no restart.

Every change happens on the process's loop: p4p's threads hand their
updates over through ``call_threadsafe`` (docs/channels.md).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from malcolm.core import (
    Alarm,
    Attribute,
    Block,
    ChoiceMeta,
    Method,
    NotWriteableError,
    StringMeta,
    from_dict,
)
from malcolm.core.metas import plain

from ..backends import backend_for
from ..channel import ChannelTimeoutError, ConnectionState, DisconnectedError
from .client_backend import PvaBackend
from .client_channel import PvaChannel, StructureReading
from .client_convert import args_value
from .convert import to_dict as to_plain

if TYPE_CHECKING:
    from malcolm.core import Process

__all__ = ["CONNECT_TIMEOUT", "RemoteBlock"]

log = logging.getLogger(__name__)

#: seconds ``start`` waits for the server before going on without it
CONNECT_TIMEOUT = 5.0


def _without_writeable(meta: Any) -> Any:
    if isinstance(meta, dict):
        return {k: v for k, v in meta.items() if k != "writeable"}
    return meta


class RemoteBlock:
    """A local block mirroring block ``mri`` served at ``address`` over
    pvAccess; see the module's docstring."""

    def __init__(
        self,
        mri: str,
        address: str,
        connect_timeout: float = CONNECT_TIMEOUT,
    ) -> None:
        self.mri = mri
        self.address = address
        self.connect_timeout = connect_timeout
        self.block = Block(mri, f"Client of {mri} at pva://{address}")
        self.process: Process | None = None
        #: as a Controller's (nobody is told of state changes here)
        self.state_listeners: list[Any] = []
        self._backend: PvaBackend | None = None
        self._channel: PvaChannel | None = None
        self._data: dict[str, Any] = {}
        placeholder = Attribute(
            "health",
            StringMeta("Why the block is in Fault"),
            f"{self.where}: not connected yet",
            alarm=Alarm.disconnected(f"{self.where}: not connected yet"),
        )
        self.block.add(placeholder)
        # until the server is found: a state, as every block has (serve's
        # state log and listing read it), not usable
        self.block.add(
            Attribute(
                "state",
                ChoiceMeta(["Disabled"], "State of the block"),
                "Disabled",
                alarm=Alarm.disconnected(f"{self.where}: not connected yet"),
            )
        )

    @property
    def where(self) -> str:
        """``pva://HOST:PORT/MRI``: the remote block, as messages name it."""
        return f"pva://{self.address}/{self.mri}"

    @property
    def health(self) -> Attribute:
        return self.block.attribute("health")

    @property
    def connected(self) -> bool:
        channel = self._channel
        return channel is not None and channel.state is ConnectionState.CONNECTED

    # ---- lifecycle
    async def start(self) -> None:
        """Monitor the remote block; wait up to ``connect_timeout`` s for it,
        then go on without it (``health`` says so; p4p keeps searching)."""
        assert self.process is not None
        backend = backend_for(self.process, "pva")
        if not isinstance(backend, PvaBackend):
            message = (
                f"{self.where}: the process's 'pva' channel backend is"
                f" {type(backend).__name__}, which cannot reach another process"
            )
            self._show_lost(message)
            return
        self._backend = backend.for_address(self.address)
        channel = self._channel = self._backend.channel(self.mri)
        channel.subscribe(self._on_reading)
        channel.watch_connection(self._on_connection)
        try:
            await channel.connect(self.connect_timeout)
        except ChannelTimeoutError:
            self._show_lost(
                f"{self.where}: not connected within {self.connect_timeout} s;"
                " still trying"
            )

    async def stop(self) -> None:
        channel, self._channel = self._channel, None
        if channel is not None:
            await channel.close()

    # ---- what the process calls
    def _check_connected(self) -> PvaBackend:
        channel = self._channel
        if channel is None or self._backend is None:
            raise DisconnectedError(f"{self.where}: not started")
        if channel.state is not ConnectionState.CONNECTED:
            raise DisconnectedError(
                f"{self.where}: {channel.message or 'not connected'}"
            )
        return self._backend

    async def put(self, name: str, value: Any) -> None:
        """Put ``value`` to the remote attribute ``name`` and wait until the
        server has done it (its error is re-raised)."""
        attr = self.block.attribute(name)
        backend = self._check_connected()
        if not attr.meta.writeable:
            raise NotWriteableError(f"{self.mri}.{name} is read-only")
        value = attr.validate(value)
        await backend.put(f"{self.mri}.{name}", {"value": plain(value)})

    async def call(self, name: str, params: Mapping[str, Any] | None = None) -> Any:
        """Call the remote method ``name``; returns what it returns (a dict),
        or raises the server's error."""
        method = self.block.method(name)
        backend = self._check_connected()
        takes = method.meta.takes
        args: dict[str, Any] = {}
        for key, value in dict(params or {}).items():
            meta = takes.elements.get(key)
            as_data = getattr(meta, "as_data", None)
            args[key] = as_data(value) if as_data is not None else plain(value)
        result = await backend.rpc(f"{self.mri}.{name}", args_value(args, takes))
        returned = to_plain(result)
        if isinstance(returned, dict):
            returned.pop("typeid", None)
        return returned

    def writer_of(self, field: str) -> str | None:
        """Who is writing ``field`` here: nobody in this process."""
        return None

    def _update_writeable(self) -> None:
        """The builder's call after adding parts: a mirror has none."""

    # ---- the remote block's updates
    def _on_reading(self, reading: Any) -> None:
        data = reading.value
        if not isinstance(data, dict):
            log.warning("%s: the server sent %r, not a block", self.where, data)
            return
        changed = getattr(reading, "changed", None)
        if not isinstance(reading, StructureReading) or changed is None:
            self._sync_all(data)
            return
        for name in changed:
            if name == "meta":
                self._sync_meta(data.get("meta"))
            elif name != "typeid" and name in data:
                self._sync_field(name, data[name])
        self._data = data

    def _sync_all(self, data: dict[str, Any]) -> None:
        self._data = data
        self._sync_meta(data.get("meta"))
        for name, value in data.items():
            if name not in ("typeid", "meta"):
                self._sync_field(name, value)
        for name in list(self.block):
            if name not in data:
                self.block.remove(name)

    def _sync_meta(self, meta: Any) -> None:
        if not isinstance(meta, dict):
            return
        own = self.block.meta
        before = own.to_dict()
        for key in ("description", "tags", "writeable", "label"):
            if key in meta:
                value = tuple(meta[key]) if key == "tags" else meta[key]
                setattr(own, key, value)
        after = own.to_dict()
        if after != before:
            self.block.notify([[["meta"], after]])

    def _sync_field(self, name: str, d: Any) -> None:
        try:
            new = from_dict(d, name)
        except Exception as e:  # a server's bad structure must not stop us
            log.warning("%s: field %s: %s", self.where, name, e)
            return
        old = self.block[name] if name in self.block else None
        old_d = old.to_dict() if old is not None else None
        if (
            isinstance(old, Attribute)
            and isinstance(new, Attribute)
            and old_d is not None
            and old_d.get("typeid") == d.get("typeid")
            and _without_writeable(old_d.get("meta"))
            == _without_writeable(new.meta.to_dict())
        ):
            old.set_writeable(new.meta.writeable)
            old.set_value(new.value, new.alarm, new.timeStamp, validate=False)
            return
        if (
            isinstance(old, Method)
            and isinstance(new, Method)
            and old_d is not None
            and _without_writeable(old_d.get("meta"))
            == _without_writeable(new.meta.to_dict())
        ):
            old.set_writeable(new.meta.writeable)
            changes = []
            for log_name in ("took", "returned"):
                log_d = getattr(new, log_name).to_dict()
                if old_d.get(log_name) != log_d:
                    setattr(old, log_name, getattr(new, log_name))
                    changes.append([[name, log_name], log_d])
            if changes:
                self.block.notify(changes)
            return
        if isinstance(new, Attribute | Method):
            self.block.add(new)

    # ---- the connection
    def _on_connection(self, state: ConnectionState, message: str) -> None:
        if state is ConnectionState.DISCONNECTED:
            self._show_lost(f"{self.where}: {message or 'connection lost'}")

    def _show_lost(self, message: str) -> None:
        """INVALID alarms on every attribute, ``health`` saying why, every
        method not writeable (until the server is back)."""
        alarm = Alarm.disconnected(message)
        for name, attr in self.block.attributes.items():
            if name == "health":
                attr.set_value(message, alarm=alarm, validate=False)
            else:
                attr.set_alarm(alarm)
        for method in self.block.methods.values():
            method.set_writeable(False)
        log.debug("%s", message)  # serve logs the change of health

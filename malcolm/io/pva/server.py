"""Serve every block of a Process over pvAccess (interop.md §2), on p4p.

``await start_pva_server(process, port)`` returns a :class:`PvaServer`
(``await server.close()`` stops it). Channels are made when a client asks
for them: ``<mri>`` (the whole block) and ``<mri>.<field>`` (one field, or
``meta``). Each is a p4p ``SharedPV`` fed by one ``process.subscribe`` of
its path: the first monitor update is the whole structure, each later
delta of the process becomes exactly one update carrying only the fields
it changed. A change of shape (a field added or removed, a meta whose
value type differs) reopens the channel with the new type; a block or
field that goes away closes it. Channels nobody is connected to are let go.

p4p calls this module from its own threads: name look-ups only read, and
every put, method call and channel opening is handed to the process's loop
with ``Process.call_threadsafe`` (docs/channels.md). Errors go back to the
client as ``"<ExceptionType>: <message>"`` and change nothing.

This module is the server and its names; a channel is
:mod:`malcolm.io.pva.channel` (its puts and calls
:mod:`malcolm.io.pva.channel_requests`).
"""

from __future__ import annotations

import asyncio
import logging
import os
import threading
from typing import Any

from p4p.server import DynamicProvider, Server
from p4p.server.raw import SharedPV

from malcolm.core import Process, call_threadsafe

from .channel import _Channel, _Handler
from .errlog import route_errlog
from .ops import LoopSharedPV, OpRunner, error_text

__all__ = ["PvaServer", "start_pva_server"]

log = logging.getLogger(__name__)

#: seconds a channel nobody is connected to is kept (a client reconnecting)
RELEASE_DELAY = 2.0


class _Names:
    """p4p's DynamicProvider handler: which names exist, and their channels."""

    def __init__(self, server: PvaServer) -> None:
        self.server = server

    def testChannel(self, name: str) -> Any:
        try:
            if self.server._path_of(name) is not None:
                return True
        except Exception as e:  # a look-up must never stop the server
            log.debug("pva search %r: %s", name, error_text(e))
        # not cached as missing: a block made later is found at once
        return DynamicProvider.NotYet

    def makeChannel(self, name: str, peer: str) -> Any:
        try:
            return self.server._channel(name)
        except Exception as e:
            log.debug("pva channel %r: %s", name, error_text(e))
            return None


class PvaServer:
    """A pvAccess server for every block of ``process`` (see the module doc)."""

    def __init__(
        self, process: Process, port: int = 5075, conf: dict[str, str] | None = None
    ) -> None:
        self.process = process
        self.port = port
        self.conf = dict(conf or {})
        self._lock = threading.Lock()
        self._channels: dict[str, _Channel] = {}
        # closed SharedPVs of released channels, by name, for reuse: p4p does
        # not give back all of a destroyed SharedPV's memory, so a name that
        # is let go and asked for again would grow the server each time
        self._kept: dict[str, tuple[SharedPV, _Handler]] = {}
        self._provider: DynamicProvider | None = None
        self._server: Server | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        # puts and calls: run on the loop; those waiting in _tasks
        self._ops = OpRunner()
        self._tasks: set[asyncio.Task[Any]] = self._ops.tasks

    @property
    def address(self) -> str:
        """``host:port`` the server listens on (its TCP port)."""
        if self._server is None:
            return f"0.0.0.0:{self.port}"
        conf = self._server.conf()
        port = conf.get("EPICS_PVAS_SERVER_PORT", str(self.port))
        hosts = conf.get("EPICS_PVAS_INTF_ADDR_LIST", "").split() or ["0.0.0.0"]
        return f"{hosts[0].split(':')[0]}:{port}"

    def start(self) -> None:
        """Listen (on the process's loop thread, before or after it starts)."""
        self._loop = asyncio.get_running_loop()
        route_errlog()
        # the environment's EPICS_PVA* settings, but always this port
        conf = {k: v for k, v in os.environ.items() if k.startswith("EPICS_PVA")}
        conf["EPICS_PVAS_SERVER_PORT"] = str(self.port)
        conf.update(self.conf)
        self._provider = DynamicProvider(f"malcolm-{id(self)}", _Names(self))
        try:
            self._server = Server(providers=[self._provider], conf=conf, useenv=False)
        except RuntimeError as e:
            raise RuntimeError(
                f"pvAccess port {self.port}: {e} (--pva-port 0 serves no pvAccess)"
            ) from None

    async def close(self) -> None:
        """Stop serving: every client is disconnected."""
        server, self._server = self._server, None
        if server is not None:
            server.stop()
        with self._lock:
            channels = list(self._channels.values())
            self._channels.clear()
            kept = [pv for pv, _ in self._kept.values()]
            self._kept.clear()
        for chan in channels:
            chan.close()
        for pv in kept:
            pv.close(destroy=True)
        self._ops.close()

    # ---- names (any thread)
    def _path_of(self, name: str) -> list[str] | None:
        mris = self._mris()
        if name in mris:
            return [name]
        mri, dot, field = name.rpartition(".")
        if dot and mri in mris:
            block = self.process.get_block(mri)
            if field == "meta" or field in block:
                return [mri, field]
        return None

    def _mris(self) -> list[str]:
        for _ in range(3):
            try:
                return self.process.mris
            except RuntimeError:  # the dict changed while copied: again
                continue
        return []

    def _channel(self, name: str) -> SharedPV | None:
        path = self._path_of(name)
        if path is None:
            return None
        with self._lock:
            chan = self._channels.get(name)
            if chan is None:
                chan = _Channel(self, name, path)
                chan.prime()
                self._channels[name] = chan
                self._call(chan.open)
            chan.made += 1
            return chan.pv

    def _shared_pv(self, name: str) -> tuple[SharedPV, _Handler]:
        """The kept PV of ``name`` (under the lock), or a new one."""
        kept = self._kept.pop(name, None)
        if kept is not None:
            return kept
        handler = _Handler()
        assert self._loop is not None
        return LoopSharedPV(self._loop, handler), handler

    def _keep_pv(self, name: str, pv: SharedPV, handler: _Handler) -> None:
        with self._lock:
            if self._server is not None and name not in self._kept:
                self._kept[name] = (pv, handler)
                return
        pv.close(destroy=True)

    def _schedule_release(self, chan: _Channel) -> None:
        made = chan.made
        loop = self._loop
        if loop is not None and not loop.is_closed():
            loop.call_soon_threadsafe(
                loop.call_later, RELEASE_DELAY, chan.release, made
            )

    def _forget(self, chan: _Channel, made: int | None = None) -> None:
        """Drop ``chan``; with ``made`` (a release), only if it is still
        unused since then (checked under the lock makeChannel takes, so no
        client gets it), keeping its PV for the next channel of that name."""
        with self._lock:
            if made is not None and (chan.clients or chan.made != made):
                return
            if self._channels.get(chan.name) is chan:
                del self._channels[chan.name]
        chan.close(keep=made is not None and self._server is not None)

    def _call(self, func: Any, *args: Any) -> Any:
        if self._loop is None:
            raise RuntimeError("the pvAccess server has not started")
        return call_threadsafe(self._loop, func, *args)

    @property
    def channel_names(self) -> list[str]:
        """The names that have a channel now (for tests and diagnostics)."""
        with self._lock:
            return list(self._channels)


async def start_pva_server(
    process: Process, port: int = 5075, conf: dict[str, str] | None = None
) -> PvaServer:
    """Serve every block of ``process`` on ``port`` (0: any free port); call on
    the loop the process runs (or will run) on. ``conf`` adds p4p server
    settings (``EPICS_PVAS_*``)."""
    server = PvaServer(process, port, conf)
    server.start()
    return server

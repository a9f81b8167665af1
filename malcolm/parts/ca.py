"""More Channel Access sections: ``ca.DoubleArray``, ``ca.LongArray``, ``ca.Action``.

``ca.DoubleArray`` / ``ca.LongArray`` are :class:`~malcolm.parts.soft.CAPart`
attributes holding a 1-d array (a waveform record), with the same keys as
``ca.Double`` (``pv``, ``rbv``/``rbv_suffix``, ``writeable``, ``widget``,
``group``, ``low``/``high``, ``units``, ``precision``): the limits bound
every element.

``ca.Action`` makes a **method** (no arguments) named after the section: it
puts ``value`` (default 1) to ``pv`` with completion, then waits until
``status_pv`` reports ``good_status`` (default ``Success``), for at most
``timeout`` seconds (default 10). A status of ``bad_status`` (default
``Failure``) ends the wait at once. Either failure raises an error naming
the block, the method, the status and, with ``message_pv``, what that PV
says. Its channels connect in Reset and report lost connections in
``health`` like an attribute's.

The status it judges is what the block's own attributes are given: after
the put it reads the status with ``Channel.current`` (a get, then the wait
for the monitor to bring that value), and then follows the monitor. So when
the method returns, every attribute of the process bound to ``status_pv``
(a motor's ``doneMoving`` for ``stop``) shows the good status already.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

from malcolm.core import Meta, MethodMeta, NumberArrayMeta
from malcolm.fsm import Stateful
from malcolm.io import (
    Channel,
    ChannelError,
    ChannelInfo,
    ChannelTimeoutError,
    ConnectionState,
    Reading,
    backend_for,
)

from .base import Part, PartRegistrar
from .channel import CONNECT_TIMEOUT
from .soft import _NumberPart

if TYPE_CHECKING:
    from malcolm.hooks import Task

__all__ = ["CAActionPart", "CADoubleArrayPart", "CALongArrayPart"]


class CADoubleArrayPart(_NumberPart):
    """``ca.DoubleArray``: a float64 array attribute (a waveform)."""

    input_widget = "table"

    def make_meta(
        self, description: str, tags: Sequence[str], writeable: bool, label: str
    ) -> Meta:
        return NumberArrayMeta(
            self.dtype, description, tags, writeable, label, display=self.display
        )

    def meta_from_info(self, meta: Meta, info: ChannelInfo) -> Meta | None:
        """Limits, units and precision the channel reports, where the
        definition gave none (the limits bound each element)."""
        assert isinstance(meta, NumberArrayMeta)
        found = self.display_from_info(info)
        if not found:
            return None
        return NumberArrayMeta(
            self.dtype,
            meta.description,
            meta.tags,
            meta.writeable,
            meta.label,
            display={**meta.display, **found},
        )


class CALongArrayPart(CADoubleArrayPart):
    """``ca.LongArray``: an int32 array attribute (a waveform of longs)."""

    dtype = "int32"


class CAActionPart(Part):
    """``ca.Action``: a method that puts to ``pv`` and waits for a good status."""

    def __init__(
        self,
        name: str,
        pv: str,
        status_pv: str,
        good_status: str = "Success",
        bad_status: str | None = "Failure",
        message_pv: str | None = None,
        value: Any = 1,
        timeout: float = 10.0,
        description: str = "",
        label: str = "",
    ) -> None:
        if not name.isidentifier():
            raise ValueError(f"method name {name!r} is not an identifier")
        if not pv or not status_pv:
            raise ValueError("needs a 'pv' to put to and a 'status_pv' to watch")
        if float(timeout) <= 0:
            raise ValueError(f"timeout must be positive, not {timeout}")
        super().__init__(name)
        self.pv, self.status_pv, self.message_pv = pv, status_pv, message_pv
        self.good, self.bad = str(good_status), bad_status
        self.value, self.timeout = value, float(timeout)
        self.description = (
            description or f"Put {value!r} to {pv}, wait for {good_status}"
        )
        self.label = label
        self._channels: dict[str, Channel] = {}
        self._ends: list[Callable[[], None]] = []
        self._registrar: PartRegistrar | None = None
        self._mri = ""

    def setup(self, registrar: PartRegistrar) -> None:
        self._registrar = registrar
        self._mri = registrar.mri
        meta = MethodMeta(description=self.description, label=self.label)
        registrar.add_method(self.act, self.name, meta)

    # ---- connecting
    @Stateful.Reset
    async def connect(self, task: Task) -> None:
        """Connect the put, status (and message) channels; report what does
        not connect in health (they keep trying)."""
        if not self._channels or any(
            c.state is ConnectionState.CLOSED for c in self._channels.values()
        ):
            backend = backend_for(task.process, "ca")
            self._channels = {"put": backend.channel(self.pv, self.pv, default=0)}
            self._channels["status"] = backend.channel(self.status_pv, default="")
            if self.message_pv:
                self._channels["message"] = backend.channel(self.message_pv, default="")
            self._ends = [
                c.watch_connection(self._on_connection) for c in self._channels.values()
            ]
        await asyncio.gather(
            *(self._connect(c) for c in self._channels.values()),
        )
        self._on_connection(ConnectionState.CONNECTED, "")

    async def _connect(self, channel: Channel) -> None:
        try:
            await channel.connect(CONNECT_TIMEOUT)
        except ChannelTimeoutError:
            pass  # reported by _on_connection; it keeps trying

    def _on_connection(self, state: ConnectionState, message: str) -> None:
        assert self._registrar is not None
        lost = [
            f"{c.read}: {c.message or 'not connected'}"
            for c in self._channels.values()
            if c.state is not ConnectionState.CONNECTED
        ]
        self._registrar.report_health("; ".join(lost) if lost else None)

    @Stateful.Disable
    async def disconnect(self, task: Task) -> None:
        for end in self._ends:
            end()
        self._ends = []
        for channel in self._channels.values():
            await channel.close()
        assert self._registrar is not None
        self._registrar.report_health(None)

    # ---- the method
    def _fail(self, why: str) -> ChannelError:
        return ChannelError(f"{self._mri}.{self.name}: {why}")

    async def _why(self, status: Any) -> str:
        text = f"{self.status_pv} is {status!r}"
        channel = self._channels.get("message")
        if channel is not None:
            try:
                text += f" ({(await channel.get()).value})"
            except ChannelError:
                pass
        return text

    async def act(self) -> None:
        """Put, then wait until the status PV reports good."""
        if not self._channels:
            raise self._fail("not connected (the block has not started)")
        status = self._channels["status"]
        changed: asyncio.Queue[Reading] = asyncio.Queue()
        end = status.subscribe(changed.put_nowait)
        try:
            loop = asyncio.get_running_loop()
            try:
                await self._channels["put"].put(self.value, self.timeout)
                deadline = loop.time() + self.timeout
                # what the get reads, once the monitor (so every attribute
                # bound to the status PV) has caught up with it
                reading = await status.current(self.timeout)
            except ChannelError as e:  # the same kind, naming the method
                raise type(e)(f"{self._mri}.{self.name}: {e}") from None
            while not changed.empty():  # older than (or as old as) ``reading``
                changed.get_nowait()
            while str(reading.value) != self.good:
                if self.bad is not None and str(reading.value) == self.bad:
                    raise self._fail(await self._why(reading.value))
                left = deadline - loop.time()
                try:
                    reading = await asyncio.wait_for(changed.get(), max(left, 0))
                except TimeoutError:
                    why = await self._why(reading.value)
                    raise self._fail(
                        f"{why}, not {self.good!r}, {self.timeout} s after the put"
                    ) from None
        finally:
            end()

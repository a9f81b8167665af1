"""Zebra2CapturePart (section ``zebra2.Capture``): PCAP capture into HDF5.

A runnable block's part that captures what a Zebra2 box's PCAP sends:

- **configure** takes ``captureFields`` (``["COUNTER1.OUT Value",
  "PCAP.TS_TRIG Value", ...]``: ``*CAPTURE=`` then one ``F.CAPTURE=option``
  each; empty keeps what the box has) and ``captureFile`` (the HDF5 file),
  and connects to the data port (``XML FRAMED SCALED``), so the box has a
  data client before it is armed;
- **run** arms (``*PCAP.ARM=``) and streams the experiment into the file
  (:class:`~malcolm.io.zebra2.hdf.CaptureFile`, written in a worker
  thread) until the box's ``END``: one dataset per captured column with
  its units, scale and offset (a later run of the same scan, after a
  breakpoint, appends to the file). Progress is the samples written. Once the
  scan's steps are all captured the box is disarmed (the samples it sent
  meanwhile are written too). The run fails if the ``END`` line's reason is
  not ``Ok`` or ``Disarmed`` (a ``Data overrun``: samples were lost), or if
  the samples written are not the number it reports;
- **abort** disarms (``*PCAP.DISARM=``) and closes the data connection.

``samplesWritten`` shows the samples in the file; ``captureEnd`` the
``END`` line's reason.
"""

from __future__ import annotations

import contextlib
from typing import TYPE_CHECKING, Any

from malcolm.core import MalcolmError, NumberMeta, StringArrayMeta, StringMeta
from malcolm.fsm import RunnableDevice
from malcolm.io.zebra2 import (
    DEFAULT_CONTROL_PORT,
    DEFAULT_DATA_PORT,
    DEFAULT_TIMEOUT,
    ControlClient,
)

from .base import Part, PartRegistrar

if TYPE_CHECKING:
    from malcolm.hooks import Task
    from malcolm.io.zebra2.data import DataClient

__all__ = ["Zebra2CapturePart"]


class Zebra2CapturePart(Part):
    """Captures a box's PCAP data into an HDF5 file during a run."""

    def __init__(
        self,
        name: str = "pcap",
        host: str = "localhost",
        control_port: int = DEFAULT_CONTROL_PORT,
        data_port: int = DEFAULT_DATA_PORT,
        timeout: float = DEFAULT_TIMEOUT,
    ) -> None:
        super().__init__(name)
        self.host = host
        self.control_port = int(control_port)
        self.data_port = int(data_port)
        self.timeout = float(timeout)
        self.control: ControlClient | None = None
        self.data: DataClient | None = None
        self.file_name = ""

    def setup(self, registrar: PartRegistrar) -> None:
        registrar.add_configure_arg(
            "captureFields",
            StringArrayMeta("Fields to capture: 'BLOCK.FIELD Option' each"),
            default=(),
        )
        registrar.add_configure_arg(
            "captureFile", StringMeta("HDF5 file the samples go to"), required=True
        )
        self.samples = registrar.add_attribute(
            "samplesWritten", NumberMeta("int64", "Samples written to the file"), 0
        )
        self.end = registrar.add_attribute(
            "captureEnd", StringMeta("END of the last experiment: samples, reason")
        )

    async def _control(self) -> ControlClient:
        client = self.control
        if client is None or not client.connected:
            client = ControlClient(self.host, self.control_port, self.timeout)
            await client.connect()
            self.control = client
        return client

    async def _close(self) -> None:
        data, self.data = self.data, None
        if data is not None:
            await data.close()
        control, self.control = self.control, None
        if control is not None:
            await control.close()

    @RunnableDevice.Configure
    async def configure(self, task: Task, device: Any) -> None:
        await self._close()
        control = await self._control()
        fields = [
            str(f).strip() for f in (device.captureFields or ()) if str(f).strip()
        ]
        if fields:
            commands = ["*CAPTURE="]
            for entry in fields:
                target, _, option = entry.partition(" ")
                commands.append(f"{target}.CAPTURE={option.strip() or 'Value'}")
            for command, reply in zip(commands, await control.send_many(commands)):
                if isinstance(reply, Exception):
                    raise MalcolmError(f"{task.part}: capture {command}: {reply}")
        from malcolm.io.zebra2.data import DataClient  # pandablocks: when used

        self.file_name = str(device.captureFile)
        self.data = DataClient(self.host, self.data_port, True, self.timeout)
        await self.data.connect()
        self.samples.set_value(0)
        self.end.set_value("")

    @RunnableDevice.Run
    async def run(self, task: Task, device: Any) -> None:
        from malcolm.io.zebra2.hdf import capture_to_file  # h5py: when used

        data = self.data
        assert data is not None, "configure first"
        control = await self._control()
        await control.send("*PCAP.ARM=")
        wanted = int(device.configuredSteps) - int(device.completedSteps)
        start = int(device.completedSteps)
        disarmed = False

        before = int(self.samples.value) if start > 0 else 0

        async def on_rows(rows: int) -> None:
            nonlocal disarmed
            self.samples.set_value(before + rows)
            task.report_progress(start + min(rows, wanted))
            if rows >= wanted > 0 and not disarmed:
                disarmed = True
                await control.send("*PCAP.DISARM=")

        # a later run of the scan goes on with the file of the first
        written, end = await capture_to_file(
            data, self.file_name, on_rows, append=start > 0
        )
        if end is None:
            raise MalcolmError(f"{task.part}: the capture ended with no END")
        reason = end.reason.value
        self.end.set_value(f"{end.samples} {reason}")
        if reason not in ("Ok", "Disarmed"):
            raise MalcolmError(
                f"{task.part}: the capture ended with END {end.samples} {reason}"
                f" ({written} samples written to {self.file_name})"
            )
        if end.samples != written:
            raise MalcolmError(
                f"{task.part}: the box reported {end.samples} samples,"
                f" {written} were written to {self.file_name}"
            )
        task.report_progress(start + wanted)

    @RunnableDevice.Abort
    async def abort(self, task: Task, device: Any) -> None:
        with contextlib.suppress(Exception):
            control = await self._control()
            await control.send("*PCAP.DISARM=")
        await self._close()

    @RunnableDevice.PostRunReady
    async def post_run(self, task: Task, device: Any) -> None:
        await self._close()

"""Zebra2ScanPart (section ``zebra2.Scan``): the ZebraManager's scan.

A runnable block's part that makes a Zebra2 (PandA) box give one trigger
pulse per scan point and captures one PCAP row per pulse into
``<fileDir>/<formatName>.h5`` (docs/devices.md):

- position compare: ``PCOMP1`` on the position ``COUNTER1.OUT``, which
  ``CLOCK1`` drives at the scan's pace (two counts per point, so that each
  pulse is one count wide and falls before the next rises); the count is
  scaled (``SCALE`` 0.5, ``OFFSET`` -1) so that the position at point k's
  pulse reads k. PCAP triggers on ``PCOMP1.OUT`` while ``PCOMP1.ACTIVE``
  enables it, so an experiment ends by itself after the last pulse;
- **configure** writes the whole setup in one pipelined batch, connects the
  data port, makes the empty file and arms PCAP (``*PCAP.ARM=``); the
  counter's clock is stopped, so nothing is triggered yet;
- **run** sets the run's first point and pulses and starts the clock (the
  simulated motion), then waits until the experiment's ``END``: progress
  is the rows captured (the last row's point + 1);
- **seek** (after a pause) disarms, waits for the experiment's ``END``,
  sets up from the new point and re-arms; a run after a breakpoint re-arms
  the same way;
- **abort** and **disable** disarm, stop the clock and close the file and
  the connections; **reset** connects again (refused, naming the box, while
  it cannot be reached).

The box lost mid-run fails the run (the block goes to Fault) with an error
naming it: ``Zebra2 box 127.0.0.1:8888: data port ...: closed before the
END of the experiment``.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
from typing import TYPE_CHECKING, Any

from malcolm.core import BadValueError, MalcolmError, StringMeta
from malcolm.fsm import RunnableDevice
from malcolm.io.zebra2 import (
    DEFAULT_CONTROL_PORT,
    DEFAULT_DATA_PORT,
    DEFAULT_TIMEOUT,
    ControlClient,
    Zebra2Error,
)

from .base import Part, PartRegistrar
from .datasets import check_file_args
from .zebra2_scan_datasets import dataset_rows, datasets_meta

if TYPE_CHECKING:
    from malcolm.hooks import Task

    from .zebra2_scan_capture import CaptureStream, Experiment

__all__ = ["Zebra2ScanPart", "run_commands", "setup_commands"]

#: the END reasons of an experiment that lost nothing
GOOD_ENDS = ("Ok", "Disarmed")
#: the simulated encoder's mux inputs: stopped, then moving
STOP = ["PCOMP1.ENABLE=ZERO", "CLOCK1.ENABLE=ZERO", "COUNTER1.ENABLE=ZERO"]
START = ["COUNTER1.ENABLE=ONE", "PCOMP1.ENABLE=ONE", "CLOCK1.ENABLE=ONE"]


def _us(seconds: float) -> str:
    return f"{seconds * 1e6:.3f}"


def position_commands(first: int, end: int, period: float) -> list[str]:
    """Point ``first`` .. ``end - 1``, one every ``period`` seconds."""
    return [
        f"CLOCK1.PERIOD={_us(period / 2)}",
        f"CLOCK1.WIDTH={_us(period / 4)}",
        f"COUNTER1.START={2 * first}",
        f"PCOMP1.START={2 * first + 2}",
        f"PCOMP1.PULSES={end - first}",
    ]


def setup_commands(first: int, end: int, period: float) -> list[str]:
    """The whole setup, stopped, ready for ``*PCAP.ARM=``."""
    return [
        *STOP,
        "CLOCK1.PERIOD.UNITS=us",
        "CLOCK1.WIDTH.UNITS=us",
        "COUNTER1.TRIG=CLOCK1.OUT",
        "COUNTER1.TRIG_EDGE=Rising",
        "COUNTER1.STEP=1",
        "COUNTER1.OUT.SCALE=0.5",
        "COUNTER1.OUT.OFFSET=-1",
        "PCOMP1.INP=COUNTER1.OUT",
        "PCOMP1.STEP=2",
        "PCOMP1.WIDTH=1",
        "PCOMP1.DIR=Positive",
        "PCOMP1.RELATIVE=Absolute",
        "PCAP.TRIG=PCOMP1.OUT",
        "PCAP.TRIG_EDGE=Rising",
        "PCAP.GATE=PCOMP1.ACTIVE",
        "PCAP.ENABLE=PCOMP1.ACTIVE",
        "*CAPTURE=",
        "COUNTER1.OUT.CAPTURE=Value",
        "PCAP.TS_TRIG.CAPTURE=Value",
        *position_commands(first, end, period),
    ]


def run_commands(first: int, end: int, period: float) -> list[str]:
    """What a run writes: its points, then the clock started."""
    return [*position_commands(first, end, period), *START]


class Zebra2ScanPart(Part):
    """One trigger pulse and one PCAP row per scan point of a Zebra2 box."""

    def __init__(
        self,
        name: str = "zebra",
        host: str = "localhost",
        control_port: int = DEFAULT_CONTROL_PORT,
        data_port: int = DEFAULT_DATA_PORT,
        timeout: float = DEFAULT_TIMEOUT,
        default_period: float = 0.01,
    ) -> None:
        super().__init__(name)
        if not float(default_period) > 0:
            raise ValueError(f"default_period must be > 0 s, not {default_period}")
        self.host = host
        self.control_port = int(control_port)
        self.data_port = int(data_port)
        self.timeout = float(timeout)
        self.default_period = float(default_period)
        self.control: ControlClient | None = None
        self.stream: CaptureStream | None = None
        self.path = ""

    @property
    def address(self) -> str:
        return f"{self.host}:{self.control_port}"

    def setup(self, registrar: PartRegistrar) -> None:
        self.default_name = registrar.mri.split(":")[-1].lower() or "zebra"
        registrar.add_configure_arg(
            "fileDir",
            StringMeta("Directory of the raw file ('' = no file)"),
            default="",
        )
        registrar.add_configure_arg(
            "formatName",
            StringMeta("The raw file is <fileDir>/<formatName>.h5"),
            default=self.default_name,
        )
        self.datasets = registrar.add_attribute(
            "datasets", datasets_meta(), dataset_rows("", "")
        )

    # ---- the box
    def _lost(self, e: BaseException) -> MalcolmError:
        text = str(e).removeprefix(f"{self.address}: ")
        return MalcolmError(f"Zebra2 box {self.address}: {text}")

    async def _control(self) -> ControlClient:
        client = self.control
        if client is None or not client.connected:
            client = ControlClient(self.host, self.control_port, self.timeout)
            try:
                await client.connect()
            except MalcolmError as e:
                raise self._lost(e) from None
            self.control = client
        return client

    async def _send(self, commands: list[str]) -> None:
        """One pipelined batch; the first refusal raises, naming it."""
        client = await self._control()
        try:
            replies = await client.send_many(commands)
        except MalcolmError as e:
            raise self._lost(e) from None
        for reply in replies:
            if isinstance(reply, Zebra2Error):
                raise BadValueError(f"Zebra2 box {self.address} refused {reply}")
            if isinstance(reply, Exception):
                raise self._lost(reply)

    async def _close_stream(self) -> None:
        """Stop reading the data port and close it (and the file)."""
        stream, self.stream = self.stream, None
        if stream is not None:
            await stream.close()

    async def close(self) -> None:
        """Disarm and let go of the box (the process closes this at stop)."""
        await self._stop()
        await self._close()

    def _closed_with(self, task: Task) -> None:
        """Have the process close this part's connections when it stops."""
        task.process.backends[f"zebra2.Scan {self.address} {id(self)}"] = self

    async def _close(self) -> None:
        await self._close_stream()
        control, self.control = self.control, None
        if control is not None:
            await control.close()

    async def _stop(self) -> None:
        """Disarm and stop the clock, if the box is there."""
        client = self.control
        if client is not None and client.connected:
            with contextlib.suppress(MalcolmError):
                await client.send_many(["*PCAP.DISARM=", *STOP])

    def _period(self, device: Any, step: int) -> float:
        points = device.points
        duration = None
        if points is not None and step < points.size:
            duration = points.duration_at(step)
        return float(duration) if duration and duration > 0 else self.default_period

    def _file_path(self, device: Any) -> tuple[str, str]:
        """(path of the raw file or "", its name relative to fileDir)."""
        file_dir = str(device.params.get("fileDir") or "")
        name = str(device.params.get("formatName") or self.default_name)
        if not file_dir:
            return "", ""
        return os.path.join(file_dir, f"{name}.h5"), f"{name}.h5"

    # ---- phases
    @RunnableDevice.Validate
    async def validate(self, task: Task, device: Any) -> dict[str, Any]:
        name = str(device.params.get("formatName") or self.default_name)
        check_file_args(device.mri, str(device.params.get("fileDir") or ""), name)
        return {}

    @RunnableDevice.Configure
    async def configure(self, task: Task, device: Any) -> None:
        # pandablocks, h5py and numpy: when a scan is first configured
        from malcolm.io.zebra2.data import DataClient

        from .zebra2_scan_capture import CaptureStream
        from .zebra2_scan_file import create_scan_file

        self._closed_with(task)
        await self._close_stream()
        path, filename = self._file_path(device)
        first, end = 0, int(device.configuredSteps)
        data = DataClient(self.host, self.data_port, True, self.timeout)
        # the setup, the data connection and the empty file at once
        work = [
            self._send(setup_commands(first, end, self._period(device, first))),
            self._connect_data(data),
        ]
        if path:
            meta = {"mri": device.mri, "host": self.address}
            work.append(asyncio.to_thread(create_scan_file, path, meta))
        outcomes = await asyncio.gather(*work, return_exceptions=True)
        failed = [o for o in outcomes if isinstance(o, BaseException)]
        if failed:
            await data.close()
            raise failed[0]
        self.path = path
        self.stream = CaptureStream(data, path)
        await self._send(["*PCAP.ARM="])
        prefix = str(device.params.get("formatName") or self.default_name)
        self.datasets.set_value(dataset_rows(prefix, filename))

    async def _connect_data(self, data: Any) -> None:
        try:
            await data.connect()
        except MalcolmError as e:
            raise self._lost(e) from None

    @RunnableDevice.Run
    async def run(self, task: Task, device: Any) -> None:
        stream = self.stream
        if stream is None:
            raise MalcolmError(f"{self.name}: not configured")
        first, end = int(device.completedSteps), int(device.configuredSteps)
        seen = len(stream.ended)
        await self._send(run_commands(first, end, self._period(device, first)))
        while True:
            done = self._finished(stream.ended[seen:], first, end)
            if done:
                task.report_progress(end)
                return
            current = stream.current
            if current is not None and current.last_uid > first:
                task.report_progress(min(current.last_uid, end))
            if stream.error is not None:
                raise self._lost(stream.error)
            await stream.wait_change()

    def _finished(self, ended: list[Experiment], first: int, end: int) -> bool:
        for exp in ended:
            if exp.reason not in GOOD_ENDS:
                raise MalcolmError(
                    f"Zebra2 box {self.address}: the capture ended with END"
                    f" {exp.samples} {exp.reason} ({exp.rows} rows written)"
                )
            if exp.last_uid >= end:
                return True
            if exp.reason == "Ok":
                raise MalcolmError(
                    f"Zebra2 box {self.address}: the capture ended at point"
                    f" {exp.last_uid} of {first + 1}..{end}"
                )
        return False

    async def _rearm(self, device: Any) -> None:
        """Disarm, let the experiment end, set up from completedSteps, arm."""
        stream = self.stream
        if stream is None:
            return
        await self._send(["*PCAP.DISARM=", *STOP])
        if stream.current is not None:
            try:
                async with asyncio.timeout(self.timeout):
                    while stream.current is not None and stream.error is None:
                        await stream.wait_change()
            except TimeoutError:
                raise MalcolmError(
                    f"Zebra2 box {self.address}: no END {self.timeout} s after"
                    " *PCAP.DISARM="
                ) from None
        if stream.error is not None:
            raise self._lost(stream.error)
        first = int(device.completedSteps)
        end = int(device.configuredSteps)
        if first < int(device.totalSteps):
            end = max(end, first + 1)
            period = self._period(device, first)
            await self._send([*position_commands(first, end, period), "*PCAP.ARM="])

    @RunnableDevice.Seek
    async def seek(self, task: Task, device: Any) -> None:
        await self._rearm(device)

    @RunnableDevice.PostRunArmed
    async def post_run_armed(self, task: Task, device: Any) -> None:
        await self._rearm(device)

    @RunnableDevice.PostRunReady
    async def post_run_ready(self, task: Task, device: Any) -> None:
        await self._stop()

    @RunnableDevice.Abort
    async def abort(self, task: Task, device: Any) -> None:
        await self._stop()
        await self._close_stream()

    @RunnableDevice.Disable
    async def disable(self, task: Task, device: Any) -> None:
        await self._stop()
        await self._close()

    @RunnableDevice.Reset
    async def reset(self, task: Task, device: Any) -> None:
        await self._stop()
        await self._close()
        await self._control()  # the box must be there

"""The ZebraManager's data port reader: experiments into the scan file.

A :class:`CaptureStream` is made at configure with a connected
:class:`~malcolm.io.zebra2.data.DataClient`; its task reads the box's
experiments one after another for the whole scan (each arm of PCAP is one
experiment: a run, or what a run did before a pause) and appends each to the
scan file (:class:`~.zebra2_scan_file.ScanFile`, opened at the experiment's
header and closed at its ``END``, in a worker thread). Whoever waits
(:meth:`CaptureStream.wait_change`) is woken after every chunk of rows and
every ``END``; a lost connection ends the task with the error, which
:meth:`CaptureStream.check` raises.
"""

from __future__ import annotations

import asyncio
import contextlib
from dataclasses import dataclass
from typing import TYPE_CHECKING

from pandablocks.responses import EndData, FrameData, StartData

from .zebra2_scan_datasets import POSITION
from .zebra2_scan_file import ScanFile

if TYPE_CHECKING:
    from malcolm.io.zebra2.data import DataClient

__all__ = ["CaptureStream", "Experiment"]


@dataclass
class Experiment:
    """What one experiment (one arm of PCAP) has brought so far."""

    rows: int = 0
    #: the last row's uniqueid (its point + 1); 0 before the first row
    last_uid: int = 0
    #: the ``END`` line's reason once it came ("" before)
    reason: str = ""
    #: the ``END`` line's sample count
    samples: int = 0


class CaptureStream:
    """Reads every experiment of a scan into ``path`` ("" = read only)."""

    def __init__(self, data: DataClient, path: str) -> None:
        self.data = data
        self.path = path
        #: the experiment in progress (None between experiments)
        self.current: Experiment | None = None
        #: the experiments that ended, in order
        self.ended: list[Experiment] = []
        self.error: BaseException | None = None
        self._changed = asyncio.Event()
        self._file: ScanFile | None = None
        self._task = asyncio.get_running_loop().create_task(self._read())

    @property
    def address(self) -> str:
        return self.data.address

    def _notify(self) -> None:
        self._changed.set()
        self._changed = asyncio.Event()

    async def wait_change(self) -> None:
        """Until the next chunk of rows, ``END`` or error."""
        if self.error is None and not self._task.done():
            await self._changed.wait()

    def check(self) -> None:
        """Raise the error that ended the reading, if one did."""
        if self.error is not None:
            raise self.error

    async def _read(self) -> None:
        try:
            while True:
                await self._experiment()
        except asyncio.CancelledError:
            raise
        except BaseException as e:  # noqa: BLE001 - handed to whoever waits
            self.error = e
        finally:
            await self._close_file()
            self._notify()

    async def _experiment(self) -> None:
        async for item in self.data.experiment():
            if isinstance(item, StartData):
                await self._close_file()
                self.current = Experiment()
                if self.path:
                    self._file = await asyncio.to_thread(ScanFile, self.path, item)
                self._notify()
            elif isinstance(item, FrameData):
                exp = self.current
                if exp is None:  # frames of no header: nothing to file them by
                    continue
                if self._file is not None:
                    exp.rows = await asyncio.to_thread(self._file.write, item.data)
                    exp.rows -= self._file_first
                    exp.last_uid = self._file.last_uid
                else:
                    exp.rows += len(item.data)
                    if len(item.data):
                        exp.last_uid = int(round(item.data[POSITION][-1])) + 1
                self._notify()
            elif isinstance(item, EndData):
                exp = self.current or Experiment()
                exp.reason = item.reason.value
                exp.samples = int(item.samples)
                await self._close_file(exp)
                self.current = None
                self.ended.append(exp)
                self._notify()

    @property
    def _file_first(self) -> int:
        f = self._file
        return 0 if f is None else f.first

    async def _close_file(self, exp: Experiment | None = None) -> None:
        f, self._file = self._file, None
        if f is not None:
            if exp is None:
                await asyncio.to_thread(f.close)
            else:
                await asyncio.to_thread(f.close, exp.samples, exp.reason)

    async def close(self) -> None:
        """Stop reading (the file is closed) and close the data connection."""
        task = self._task
        if not task.done():
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task
        await self._close_file()
        await self.data.close()

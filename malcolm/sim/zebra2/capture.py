"""PCAP: arm/disarm, the experiment, and its samples sent to data clients.

After ``*PCAP.ARM=`` the experiment starts when ``PCAP.ENABLE`` is high
(tier 1's dumb simulator: at once); every rising edge of ``PCAP.TRIG`` (a
clock output) while ``PCAP.GATE`` is high makes a sample; ``PCAP.ENABLE``
going low ends it with ``Ok``, ``*PCAP.DISARM=`` with the configured
completion.  Samples are made in batches for the interval since the last
batch, so a 1 MHz trigger costs a few numpy operations per batch.  A data
client whose socket buffer passes `OVERRUN_BYTES`, or a simulation more than
`OVERRUN_LAG` behind the clock, ends the experiment with ``Data overrun``
for it, as the FPGA's buffer would.
"""

from __future__ import annotations

import asyncio
import time
from datetime import UTC, datetime

import numpy as np

from .box import Box
from .clocks import ClockModel
from .columns import Column, build_columns, word_offsets
from .dataport import DataClient
from .fields import BitOutField, PosOutField
from .signals import Signals
from .values import CLOCK_HZ, Zebra2Error

BATCH = 65536
ASCII_BATCH = 4096
OVERRUN_BYTES = 256 * 1024 * 1024
OVERRUN_LAG = CLOCK_HZ  # one second of samples not yet made
KEEP = 1 << 16  # samples kept for late joiners
SYNTHETIC_PERIOD = CLOCK_HZ // 10  # tier 1's dumb simulator: 10 samples/s


def _iso(ns: int) -> str:
    seconds, frac = divmod(ns, 1_000_000_000)
    stamp = datetime.fromtimestamp(seconds, UTC).strftime("%Y-%m-%dT%H:%M:%S")
    return f"{stamp}.{frac:09d}Z"


class Capture:
    """The PCAP block's experiment state and its data clients."""

    def __init__(self, box: Box, signals: Signals, disarm_completion: str) -> None:
        self.box = box
        self.signals = signals
        self.disarm_completion = disarm_completion
        self.synthetic = box.layout.synthetic_capture
        self.clients: list[DataClient] = []
        self.armed = False
        self.started = False
        self.completion = "Ok"
        self.captured = 0
        self.columns: list[Column] = []
        self.t_start = 0
        self.t_done = 0
        self.t_prev = 0  # the last trigger (or the start)
        self.prev_pos: dict[str, int] = {}
        #: the samples so far, for a client that joins late (up to KEEP)
        self.kept: list[np.ndarray] = []
        self.arm_iso = self.start_iso = ""
        self.changed = asyncio.Event()

    # -- control port ------------------------------------------------------
    def status(self) -> str:
        taking = sum(1 for c in self.clients if c.taking)
        state = "Busy" if self.armed else "Idle"
        return f"{state} {len(self.clients)} {taking}"

    def arm(self, t: int) -> None:
        if self.armed:
            raise Zebra2Error("Data capture already in progress")
        if not self.box.capture_fields():
            raise Zebra2Error("Nothing configured for capture")
        self.armed = True
        self.started = False
        self.completion = "Busy"
        self.captured = 0
        self.columns = build_columns(self.box)
        self.arm_iso = _iso(time.time_ns())
        for client in self.clients:
            client.taking = True
            client.sent = 0
            client.overrun = False
        self._active(1)
        if self.synthetic or self._enable_high(t):
            self._start(t)

    def disarm(self, t: int) -> None:
        if self.armed:
            self.pump(t, limit=None)
            if self.synthetic and self.started:
                # the dumb simulator flushes one more sample when disarmed
                self._emit(np.array([t], dtype=np.int64))
            self._finish(self.disarm_completion)

    def rewire(self, t: int) -> None:
        """After a write: PCAP.ENABLE starts or ends the experiment."""
        if not self.armed or self.synthetic:
            return
        high = self._enable_high(t)
        if high and not self.started:
            self._start(t)
        elif not high and self.started:
            self._finish("Ok")

    def _enable_high(self, t: int) -> bool:
        return self.signals.bit_high(self._mux("PCAP.ENABLE"), t)

    def _active(self, value: int) -> None:
        if self.synthetic:
            return  # tier 1's dumb simulator never drives PCAP.ACTIVE
        active = self.box.by_key.get("PCAP.ACTIVE")
        if active and isinstance(active[0], BitOutField):
            active[0].set_live(value)

    def _start(self, t: int) -> None:
        self.started = True
        self.t_start = self.t_done = self.t_prev = t
        self.start_iso = _iso(time.time_ns())
        self.prev_pos = {}
        self.kept = []
        header = None
        for client in self.clients:
            if client.taking and client.header:
                header = header or {}
                key = (client.xml, client.raw, client.format)
                if key not in header:
                    header[key] = client.header_bytes(
                        self.columns, self.arm_iso, self.start_iso
                    )
                client.writer.write(header[key])
        self.changed.set()

    def _finish(self, reason: str) -> None:
        self.armed = self.started = False
        self.completion = reason
        for client in self.clients:
            if client.taking:
                client.taking = False
                if client.status and not client.overrun:
                    client.writer.write(client.end_bytes(self.captured, reason))
                if client.one_shot:
                    client.closed.set()
        self._active(0)
        self.changed.set()

    # -- samples -------------------------------------------------------------
    def trigger_ticks(self, t: int, limit: int) -> np.ndarray:
        """Ticks of the next triggers in (t_done, t]."""
        if self.synthetic:
            # tier 1's dumb simulator: a sample every 0.1 s after arming
            k0 = self.captured
            k1 = min((t - self.t_start) // SYNTHETIC_PERIOD, k0 + limit)
            ticks = np.arange(k0 + 1, k1 + 1, dtype=np.int64) * SYNTHETIC_PERIOD
            return self.t_start + ticks
        trig = self.signals.source(self._mux("PCAP.TRIG"))
        if isinstance(trig, int):
            return np.zeros(0, dtype=np.int64)
        if isinstance(trig, ClockModel):
            edge = self._mux("PCAP.TRIG_EDGE")
            ticks = trig.edges_between(self.t_done, t, limit, edge)
        else:
            ticks = trig.rises_between(self.t_done, t, limit)
        gate = self.signals.source(self._mux("PCAP.GATE"))
        if isinstance(gate, int):
            return ticks if gate else ticks[:0]
        return ticks[gate.out_at_array(ticks) > 0]

    def _mux(self, key: str) -> str:
        value = self.box.field(key).read()
        assert isinstance(value, str)
        return value

    def pump(self, t: int, limit: int | None = BATCH) -> int:
        """Make and send the samples up to tick ``t``; how many were made."""
        if not self.started or limit == 0:
            return 0
        made = 0
        end = self.end_tick()
        stop = t if end is None else min(t, end)
        if limit is not None and any(c.format == "ASCII" for c in self.clients):
            limit = min(limit, ASCII_BATCH)  # printing is slow: keep the loop free
        while True:
            ticks = self.trigger_ticks(stop, limit or BATCH)
            if len(ticks) == 0:
                self.t_done = max(self.t_done, stop)
                if end is not None and end <= t:
                    self._finish("Ok")  # PCAP.ENABLE fell (e.g. PCOMP.ACTIVE)
                break
            self._emit(ticks)
            made += len(ticks)
            if limit is not None:
                break
        return made

    def _emit(self, ticks: np.ndarray) -> None:
        words = self.sample_words(ticks)
        self.t_done = max(self.t_done, int(ticks[-1]))
        self.t_prev = int(ticks[-1])
        self.captured += len(ticks)
        if self.captured <= KEEP:
            self.kept.append(words)
        else:
            self.kept = []
        self._send(words)

    def end_tick(self) -> int | None:
        """When PCAP.ENABLE's source falls by itself, if it does."""
        if self.synthetic:
            return None
        enable = self.signals.source(self._mux("PCAP.ENABLE"))
        return None if isinstance(enable, int) else enable.end_tick()

    def lagging(self, t: int) -> bool:
        return self.started and t - self.t_done > OVERRUN_LAG

    def overrun(self) -> None:
        """The simulation fell too far behind: every client overruns."""
        for client in self.clients:
            if client.taking and not client.overrun:
                self._overrun(client)
        self._finish("Data overrun")

    def _overrun(self, client: DataClient) -> None:
        client.overrun = True
        if client.status:
            client.writer.write(client.end_bytes(client.sent, "Data overrun"))
        if client.one_shot:
            client.closed.set()

    def _send(self, words: np.ndarray) -> None:
        cache: dict[tuple, bytes] = {}
        for client in self.clients:
            if not client.taking or client.overrun:
                continue
            transport = client.writer.transport
            if transport.get_write_buffer_size() > OVERRUN_BYTES:
                self._overrun(client)
                continue
            key = (client.raw, client.format)
            if key not in cache:
                cache[key] = client.data_bytes(self.columns, words)
            client.writer.write(cache[key])
            client.sent += len(words)

    def sample_words(self, ticks: np.ndarray) -> np.ndarray:
        """The raw words of the samples at ``ticks``."""
        nwords = sum(c.words for c in self.columns)
        n = len(ticks)
        if self.synthetic:
            first = self.captured
            sample = np.arange(first, first + n, dtype=np.uint64)[:, None]
            index = np.arange(nwords, dtype=np.uint64)[None, :]
            return ((sample << np.uint64(8)) | index).astype(np.uint32)
        words = np.zeros((n, nwords), dtype=np.uint32)
        prev = np.empty(n, dtype=np.int64)
        prev[0] = self.t_prev
        prev[1:] = ticks[:-1]
        duration = ticks - prev
        for col, off in zip(self.columns, word_offsets(self.columns)):
            if col.kind == "bits":
                value = self._bits(col.name, ticks)
            elif col.kind == "samples":
                value = duration
            elif col.kind == "timestamp":
                value = ticks - self.t_start
                if col.name.endswith("TS_START"):
                    value = np.zeros(n, dtype=np.int64)
            else:
                value = self._position(col, ticks, duration)
            value = value.astype(np.int64)
            words[:, off] = (value & 0xFFFFFFFF).astype(np.uint32)
            if col.words == 2:
                words[:, off + 1] = ((value >> 32) & 0xFFFFFFFF).astype(np.uint32)
        return words

    def _bits(self, word: str, ticks: np.ndarray) -> np.ndarray:
        out = np.zeros(len(ticks), dtype=np.int64)
        names = self.box.field(word).fdef.attrs["BITS"].initial.get("values", [])
        for offset, name in enumerate(names):
            if not name or name == "PCAP.ACTIVE":
                out |= int(name == "PCAP.ACTIVE") << offset  # high while capturing
                continue
            source = self.signals.source(name)
            if isinstance(source, int):
                out |= source << offset
            else:
                out |= source.out_at_array(ticks) << offset
        return out

    def _position(self, col: Column, ticks: np.ndarray, duration: np.ndarray):
        block = col.name.rsplit(".", 1)[0]
        counter = self.signals.counters.get(block)
        if counter is not None:
            values = counter.value_at_array(ticks)
        else:
            state = self.box.field(col.name)
            assert isinstance(state, PosOutField)
            values = np.full(len(ticks), state.value, dtype=np.int64)
        values = ((values + (1 << 31)) % (1 << 32)) - (1 << 31)
        if col.capture == "Diff":
            before = np.empty_like(values)
            before[0] = self.prev_pos.get(col.name, int(values[0]))
            before[1:] = values[:-1]
            self.prev_pos[col.name] = int(values[-1])
            return values - before
        if col.capture in ("Sum", "Mean"):
            return values * duration
        return values

    # -- data clients ------------------------------------------------------
    async def serve_client(
        self, client: DataClient, reader: asyncio.StreamReader
    ) -> None:
        """Keep a data client until it closes (or, if one-shot, until END)."""
        self.clients.append(client)
        try:
            if self.armed:
                client.taking = True  # a late joiner gets the whole experiment
                if self.started and client.header:
                    client.writer.write(
                        client.header_bytes(self.columns, self.arm_iso, self.start_iso)
                    )
                if self.started and self.kept:
                    words = np.concatenate(self.kept)
                    client.writer.write(client.data_bytes(self.columns, words))
                    client.sent = len(words)
            eof = asyncio.ensure_future(reader.read())
            done = asyncio.ensure_future(client.closed.wait())
            try:
                await asyncio.wait({eof, done}, return_when=asyncio.FIRST_COMPLETED)
            finally:
                eof.cancel()
                done.cancel()
            if client.closed.is_set():
                await client.writer.drain()
        finally:
            self.clients.remove(client)

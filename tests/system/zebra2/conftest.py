"""The simulated box (``malcolm sim-zebra2``) in a subprocess, and helpers.

Run these under ``../shared/tools/isolated`` (loopback only): the
simulator binds free ports on 127.0.0.1 of that private namespace.
"""

from __future__ import annotations

import asyncio
import os
import re
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
LINE = re.compile(r"control (\S+):(\d+) data (\S+):(\d+)")


class SimBox:
    """A ``malcolm sim-zebra2`` subprocess: ``kill()`` and ``start()`` again
    on the same ports."""

    def __init__(self, layout: str = "tier2") -> None:
        self.layout = layout
        self.host = "127.0.0.1"
        self.control_port = 0
        self.data_port = 0
        self.proc: subprocess.Popen[str] | None = None

    def start(self) -> None:
        cmd = [
            sys.executable,
            "-m",
            "malcolm",
            "sim-zebra2",
            "--host",
            self.host,
            "--control-port",
            str(self.control_port),
            "--data-port",
            str(self.data_port),
            "--layout",
            self.layout,
        ]
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        for _ in range(50):  # a restart may find the port not yet free
            self.proc = subprocess.Popen(
                cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env
            )
            assert self.proc.stdout is not None
            line = self.proc.stdout.readline()
            match = LINE.search(line)
            if match:
                self.control_port = int(match.group(2))
                self.data_port = int(match.group(4))
                return
            self.proc.wait(10)
            time.sleep(0.1)
        raise RuntimeError(f"sim-zebra2 did not start: {self.proc.stderr.read()}")

    def kill(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(10)
        if self.proc is not None:
            for stream in (self.proc.stdout, self.proc.stderr):
                if stream is not None:
                    stream.close()


@pytest.fixture
def sim() -> Iterator[SimBox]:
    box = SimBox()
    box.start()
    try:
        yield box
    finally:
        box.kill()


class RawClient:
    """A second client of the box: plain asyncio lines, nothing of malcolm."""

    def __init__(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter):
        self.reader = reader
        self.writer = writer

    @classmethod
    async def open(cls, sim: SimBox) -> RawClient:
        reader, writer = await asyncio.open_connection(sim.host, sim.control_port)
        return cls(reader, writer)

    async def ask(self, command: str) -> list[str]:
        """One command; its reply lines (a list reply: the items)."""
        self.writer.write(command.encode() + b"\n")
        first = (await self.reader.readline()).decode().rstrip("\n")
        if not (first.startswith("!") or first == "."):
            return [first]
        lines = []
        while first != ".":
            lines.append(first[1:])
            first = (await self.reader.readline()).decode().rstrip("\n")
        return lines

    async def close(self) -> None:
        self.writer.close()
        try:
            await self.writer.wait_closed()
        except OSError:
            pass

"""Data-port clients: their option line and the bytes of each format.

Options (any order): ``ASCII``/``BASE64``/``FRAMED``/``UNFRAMED`` (ASCII wins
over FRAMED/UNFRAMED), ``SCALED``/``RAW``, ``XML`` (header only),
``NO_HEADER``, ``NO_STATUS``, ``ONE_SHOT``, ``BARE`` (= UNFRAMED RAW
NO_HEADER NO_STATUS ONE_SHOT).  An empty line means ``ASCII SCALED``.
"""

from __future__ import annotations

import asyncio
import base64
import struct

import numpy as np

from .columns import (
    Column,
    sample_bytes,
    scaled_values,
    shown,
)

_OPTIONS = {
    "ASCII",
    "BASE64",
    "FRAMED",
    "UNFRAMED",
    "SCALED",
    "RAW",
    "XML",
    "NO_HEADER",
    "NO_STATUS",
    "ONE_SHOT",
    "BARE",
}


class DataClient:
    """One data-port connection and the format it asked for."""

    def __init__(self, options: set[str], writer: asyncio.StreamWriter) -> None:
        bare = "BARE" in options
        self.writer = writer
        self.raw = "RAW" in options or bare
        self.xml = "XML" in options
        if "ASCII" in options:
            self.format = "ASCII"
        elif "BASE64" in options:
            self.format = "Base64"
        elif "FRAMED" in options:
            self.format = "Framed"
        elif "UNFRAMED" in options or bare:
            self.format = "Unframed"
        else:
            self.format = "ASCII"
        self.header = not ("NO_HEADER" in options or bare)
        self.status = not ("NO_STATUS" in options or bare)
        self.one_shot = "ONE_SHOT" in options or bare
        self.closed = asyncio.Event()
        #: set while this client takes the current experiment
        self.taking = False
        self.sent = 0
        self.overrun = False

    @classmethod
    def from_options(cls, line: str, writer: asyncio.StreamWriter) -> DataClient | None:
        """The client for an option line, or None if an option is invalid."""
        options = {option for option in line.split(" ") if option}
        if not options <= _OPTIONS:
            return None
        return cls(options, writer)

    # -- bytes ---------------------------------------------------------------
    def header_bytes(self, columns: list[Column], arm: str, start: str) -> bytes:
        cols = shown(columns, self.raw)
        process = "Raw" if self.raw else "Scaled"
        nbytes = sample_bytes(columns, self.raw)
        types = [c.raw_type if self.raw else c.scaled_type() for c in cols]
        if self.xml:
            extra = "" if self.format == "ASCII" else f' sample_bytes="{nbytes}"'
            lines = [
                "<header>",
                f'<data arm_time="{arm}" start_time="{start}" missed="0" '
                f'process="{process}" format="{self.format}"{extra} />',
                "<fields>",
            ]
            for col, typ in zip(cols, types):
                attrs = col.header_extra()
                tail = "".join(f' {k}="{v}"' for k, v in (attrs or {}).items())
                lines.append(
                    f'<field name="{col.name}" type="{typ}" '
                    f'capture="{col.capture}"{tail} />'
                )
            lines += ["</fields>", "</header>", ""]
        else:
            lines = [
                f"arm_time: {arm}",
                f"start_time: {start}",
                "missed: 0",
                f"process: {process}",
                f"format: {self.format}",
            ]
            if self.format != "ASCII":
                lines.append(f"sample_bytes: {nbytes}")
            lines.append("fields:")
            for col, typ in zip(cols, types):
                attrs = col.header_extra()
                tail = "".join(f" {k}: {v}" for k, v in (attrs or {}).items())
                lines.append(f" {col.name} {typ} {col.capture}{tail}")
            lines.append("")
        return "".join(line + "\n" for line in lines).encode()

    def data_bytes(self, columns: list[Column], words: np.ndarray) -> bytes:
        """The bytes of a batch of samples (rows of uint32 words)."""
        if self.format == "ASCII":
            return self._ascii(columns, words)
        if self.raw:
            payload = np.ascontiguousarray(words, dtype="<u4").tobytes()
        else:
            payload = self._scaled_binary(columns, words)
        if self.format == "Framed":
            return b"BIN " + struct.pack("<I", len(payload) + 8) + payload
        if self.format == "Base64":
            chunk = sample_bytes(columns, self.raw)  # one sample per line
            return b"".join(
                b" " + base64.b64encode(payload[i : i + chunk]) + b"\x00\n"
                for i in range(0, len(payload), chunk)
            )
        return payload

    def _scaled_binary(self, columns: list[Column], words: np.ndarray) -> bytes:
        values = scaled_values(columns, words)
        cols = shown(columns, False)
        dtype = np.dtype(
            [
                (f"f{i}", "<u4" if c.kind == "bits" else "<f8")
                for i, c in enumerate(cols)
            ]
        )
        out = np.empty(len(words), dtype=dtype)
        for i, v in enumerate(values):
            out[f"f{i}"] = v
        return out.tobytes()

    def _ascii(self, columns: list[Column], words: np.ndarray) -> bytes:
        if self.raw:
            rows = (" ".join(f"0x{w:08x}" for w in row) for row in words.tolist())
            return "".join(f" {r}\n" for r in rows).encode()
        values = scaled_values(columns, words)
        cols = shown(columns, False)
        text_cols = []
        for col, v in zip(cols, values):
            if col.kind == "bits":
                text_cols.append([str(x) for x in v.tolist()])
            else:
                text_cols.append([_ascii_double(x) for x in v.tolist()])
        lines = (" " + " ".join(parts) for parts in zip(*text_cols))
        return "".join(line + "\n" for line in lines).encode()

    def end_bytes(self, samples: int, reason: str) -> bytes:
        return f"END {samples} {reason}\n".encode()


def _ascii_double(x: float) -> str:
    if x != x:
        return "nan"
    return f"{x:.10g}"

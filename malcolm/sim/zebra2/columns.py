"""Captured columns and the raw 32-bit words of each sample.

`build_columns` turns the fields whose CAPTURE is set into columns in the
server's capture order: 32-bit values first (bit words, the samples field,
positions as Value/Diff/Min/Max), then 64-bit values (timestamps, then
positions' Sum/Mean).  If Mean is captured without the samples field, a
``PCAP.SAMPLES`` column is added first; it is shown in RAW mode only.
A sample is a row of uint32 words; `scaled_values` turns words into what
SCALED mode sends.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .box import Box
from .fields import PosOutField
from .values import CLOCK_HZ, format_double

TICK = 1.0 / CLOCK_HZ
_POS_32 = ("Value", "Diff", "Min", "Max")
_POS_64 = ("Sum", "Mean")


@dataclass
class Column:
    """One captured column."""

    name: str  # "COUNTER2.OUT"
    capture: str  # "Mean"
    kind: str  # "bits", "samples", "timestamp", "pos"
    words: int  # 1 or 2
    scale: float = 1.0
    offset: float = 0.0
    units: str | None = None
    raw_only: bool = False  # the implicit PCAP.SAMPLES column

    @property
    def raw_type(self) -> str:
        if self.kind == "bits":
            return "uint32"
        return "int64" if self.words == 2 else "int32"

    def scaled_type(self) -> str:
        return "uint32" if self.kind == "bits" else "double"

    def header_extra(self) -> dict[str, str] | None:
        """scale/offset/units, or None for bit words."""
        if self.kind == "bits":
            return None
        return {
            "scale": format_double(self.scale),
            "offset": format_double(self.offset),
            "units": self.units if self.units else "(null)",
        }


def build_columns(box: Box) -> list[Column]:
    """The columns of the current capture set, in capture order."""
    first: list[Column] = []
    stamps: list[Column] = []
    second: list[Column] = []
    bits: list[Column] = []
    samples: list[Column] = []
    has_samples = False
    has_mean = False
    for state in box.capture_fields():
        capture = state.attrs["CAPTURE"]
        if state.fdef.type == "ext_out":
            sub = state.fdef.subtype
            if sub == "bits":
                bits.append(Column(state.key, capture, "bits", 1))
            elif sub == "samples":
                has_samples = True
                samples.append(Column(state.key, capture, "samples", 1, TICK, 0, "s"))
            else:
                stamps.append(Column(state.key, capture, "timestamp", 2, TICK, 0, "s"))
            continue
        assert isinstance(state, PosOutField)
        units = state.attrs.get("UNITS") or None
        for option in capture.split():
            col = Column(state.key, option, "pos", 1, state.scale, state.offset, units)
            if option in _POS_32:
                first.append(col)
            elif option in _POS_64:
                has_mean = has_mean or option == "Mean"
                col.words = 2
                second.append(col)
    implicit = []
    if has_mean and not has_samples:
        implicit = [Column("PCAP.SAMPLES", "Value", "samples", 1, TICK, 0, "s", True)]
    return implicit + bits + samples + first + stamps + second


def shown(columns: list[Column], raw: bool) -> list[Column]:
    """The columns a client sees in RAW or SCALED mode."""
    return [c for c in columns if raw or not c.raw_only]


def sample_bytes(columns: list[Column], raw: bool) -> int:
    if raw:
        return 4 * sum(c.words for c in columns)
    return sum(4 if c.kind == "bits" else 8 for c in shown(columns, raw))


def word_offsets(columns: list[Column]) -> list[int]:
    out, pos = [], 0
    for c in columns:
        out.append(pos)
        pos += c.words
    return out


def column_raw(words: np.ndarray, offset: int, col: Column) -> np.ndarray:
    """A column's raw values (int64) out of a (n, nwords) uint32 array."""
    lo = words[:, offset].astype(np.int64)
    if col.words == 2:
        hi = words[:, offset + 1].astype(np.int64)
        return (hi << 32) | lo
    if col.kind == "bits":
        return lo
    return lo - ((lo >= 1 << 31) << 32)  # int32


def scaled_values(columns: list[Column], words: np.ndarray) -> list[np.ndarray]:
    """Each shown column of SCALED mode: uint32 bit words or doubles."""
    offsets = word_offsets(columns)
    samples = None
    for col, off in zip(columns, offsets):
        if col.kind == "samples":
            samples = column_raw(words, off, col).astype(np.float64)
    out = []
    for col, off in zip(columns, offsets):
        if col.raw_only:
            continue
        raw = column_raw(words, off, col)
        if col.kind == "bits":
            out.append(raw.astype(np.uint32))
        elif col.capture == "Mean":
            with np.errstate(divide="ignore", invalid="ignore"):
                mean = raw.astype(np.float64) / samples  # type: ignore[operator]
            mean[samples == 0] = np.nan  # no samples: no mean
            out.append(mean * col.scale + col.offset)
        elif col.capture == "Sum":
            out.append(raw.astype(np.float64) * col.scale)
        else:
            out.append(raw.astype(np.float64) * col.scale + col.offset)
    return out

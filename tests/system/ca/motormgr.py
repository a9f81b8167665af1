"""What the MotorControllerManager tests share: the manager on the session's
IOC, scans as GDA sends them, and reading its raw file."""

from __future__ import annotations

from typing import Any

import h5py
import numpy as np

from malcolm.config.build import build_definition
from malcolm.core import Process
from malcolm.scan import gda

from .conftest import PREFIX

MRI = "MOTORS"


def manager_process(**values: Any) -> Process:
    """A process with the manager ``MOTORS`` on the session's IOC."""
    process = Process("motormgr-test", channels={"ca": "pyepics"})
    values = {"prefix": PREFIX, **values}
    build_definition("pmac.MotorControllerManager", values, MRI, process=process)
    return process


def line(size: int, start: float = 0.0, stop: float = 1.0, duration: float = 0.01):
    return gda.compound(gda.line("x", size, start, stop), duration=duration)


def snake(rows: int, cols: int, duration: float = 0.01) -> dict[str, Any]:
    return gda.compound(
        gda.line("y", rows, 0.0, 1.0),
        gda.line("x", cols, 0.0, 2.0, alternate=True),
        duration=duration,
    )


def read_file(path: str, axes: list[str]) -> dict[str, np.ndarray]:
    """The file's datasets (another reader: the file must be closed)."""
    with h5py.File(path, "r") as f:
        out = {"uniqueid": f["/entry/uniqueid"][()]}
        for axis in axes:
            out[f"{axis}.value_set"] = f[f"/entry/{axis}/value_set"][()]
            out[f"{axis}.value"] = f[f"/entry/{axis}/value"][()]
    return out


def last_rows(data: dict[str, np.ndarray]) -> dict[int, int]:
    """uniqueid -> the index of its last row (what an assembler keeps)."""
    return {int(u): i for i, u in enumerate(data["uniqueid"])}

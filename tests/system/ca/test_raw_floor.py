"""``benchmarks.raw_ca``: the floor's raw configures do what the managers'
do to the simulated IOC (a benchmark of traffic that did not arm anything
would measure nothing)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from benchmarks import raw_ca
from malcolm.parts.adcore import positions_xml
from malcolm.sim.beamline_ioc import SimIOC

from .conftest import PREFIX


def test_the_raw_detector_configure_arms_plugin_and_writer(
    ioc: SimIOC, tmp_path: Path
) -> None:
    raw = raw_ca.RawCA(*raw_ca.detector_pvs(PREFIX))
    try:
        other, writer = raw_ca.detector_settings(
            PREFIX, 0.01, 5, str(tmp_path), "floor", external=False
        )
        raw_ca.detector_stop(raw, PREFIX)
        raw_ca.detector_configure(
            raw, PREFIX, other, writer, [positions_xml(0, 5)], external=False
        )
        assert raw.latest[f"{PREFIX}:POS:Running_RBV"] == raw_ca.RUNNING
        assert raw.latest[f"{PREFIX}:HDF:Capture_RBV"] == raw_ca.CAPTURING
        assert raw.get(f"{PREFIX}:CAM:Exposure") == pytest.approx(0.01)
        assert (tmp_path / "floor.h5").exists()  # the IOC made it
    finally:
        raw_ca.detector_stop(raw, PREFIX)
        raw.close()


def profile(times: list[int]) -> SimpleNamespace:
    n = len(times)
    return SimpleNamespace(
        positions={"x": np.linspace(0, 1, n), "y": np.zeros(n)},
        times=np.array(times, dtype=np.int32),
        indices=np.full(n, -1, dtype=np.int32),
        size=n,
    )


def test_the_raw_motion_configure_builds_and_reads_the_status(
    ioc: SimIOC, tmp_path: Path
) -> None:
    raw = raw_ca.RawCA(raw_ca.motion_pvs(PREFIX)[0])
    made: list[bool] = []
    try:
        arrays = raw_ca.motion_arrays(PREFIX, profile([1000, 1000, 1000]))
        raw_ca.motion_configure(raw, PREFIX, arrays, lambda: made.append(True))
        assert made == [True]
        assert raw.get(f"{PREFIX}:TRAJ:NumPoints") == 3
        # a build the IOC refuses (a time of 0) fails the raw configure too
        bad = raw_ca.motion_arrays(PREFIX, profile([1000, 0, 1000]))
        with pytest.raises(RuntimeError, match="build status 2"):
            raw_ca.motion_configure(raw, PREFIX, bad)
    finally:
        raw.close()

"""Issue 13's figures for the DetectorManager alone (one device of the
hierarchy), on the simulated IOC:

    ../shared/tools/isolated .venv/bin/python -m benchmarks.detmgr

- configure of ``ADCore.DetectorManager`` (points into the position plugin,
  writer and driver set up, armed) for a 10x10 grid and a 10,000-point
  grid, median of five, each beside the demo SCAN's configure of the same
  scan (the single layer issue 13 compares the hierarchy with; target for
  the whole hierarchy: within 3x of it);
- the run's overhead per point at the simulation's shortest exposure
  (``MIN_EXPOSURE``, 0.1 ms, Internal triggering, 2000 points into an HDF5 file): the
  manager's run() less the same acquisition driven by raw pyepics puts
  (Acquire put with completion, until the writer is done), per point,
  target at most 0.1 ms a point;
- the floor of each configure: its Channel Access traffic done by the raw
  library (:mod:`benchmarks.raw_ca`: the same puts, in the manager's two
  chains at once, each put with completion, the waits for the plugin
  running and the writer capturing, the file made by the IOC), median of
  five, the manager's configure beside it as a ratio. As the manager's
  configures, each after a reset, of the same scan: the settings the IOC
  holds already are not sent again.
"""

from __future__ import annotations

import asyncio
import os
import tempfile
import time
from typing import Any

from benchmarks.table import Row, median, render
from malcolm.parts.detector_manager import MIN_EXPOSURE

PREFIX = "BENCHDET"
EXPOSURE = MIN_EXPOSURE  # the simulated driver's shortest frame
POINTS = 2000


def grid(ny: int, nx: int, duration: float) -> dict[str, Any]:
    from malcolm.scan import gda

    return gda.compound(
        gda.line("y", ny), gda.line("x", nx, alternate=True), duration=duration
    )


async def configure_times(
    mri: str, process: Any, generator: dict[str, Any], params: dict[str, Any]
) -> float:
    times = []
    for _ in range(5):
        began = time.perf_counter()
        await process.post([mri, "configure"], {"generator": generator, **params})
        times.append(time.perf_counter() - began)
        await process.post([mri, "abort"])
        await process.post([mri, "reset"])
    return median(times)


def raw_configure_times(file_dir: str, points: int) -> float:
    """Median seconds of the raw library's configure (:mod:`benchmarks.raw_ca`)
    of a ``points`` scan as the manager's (Internal triggering, the file
    ``det.h5``): a first one puts every setting (not counted), the next
    five the plugin's clearing and positions, its start and the writer's
    capture, as the manager's do."""
    from benchmarks import raw_ca
    from malcolm.parts.adcore import positions_xml
    from malcolm.parts.detector_manager import XML_BATCH

    raw = raw_ca.RawCA(*raw_ca.detector_pvs(PREFIX))
    try:
        other, writer = raw_ca.detector_settings(
            PREFIX, 0.01, points, file_dir, "det", external=False
        )
        batches = [
            positions_xml(start, min(points, start + XML_BATCH))
            for start in range(0, points, XML_BATCH)
        ]
        raw_ca.detector_stop(raw, PREFIX)
        raw_ca.detector_configure(raw, PREFIX, other, writer, batches, False)
        times = []
        for _ in range(5):
            raw_ca.detector_stop(raw, PREFIX)
            began = time.perf_counter()
            raw_ca.detector_configure(raw, PREFIX, {}, {}, batches, False)
            times.append(time.perf_counter() - began)
        raw_ca.detector_stop(raw, PREFIX)
        return median(times)
    finally:
        raw.close()


async def detector(file_dir: str) -> tuple[float, float, float]:
    from malcolm.config.build import build_definition
    from malcolm.core import Process

    process = Process("bench", channels={"ca": "pyepics"})
    build_definition(
        "ADCore.DetectorManager", {"prefix": PREFIX}, "DET", process=process
    )
    await process.start()
    try:
        params = {"fileDir": file_dir}
        small = await configure_times("DET", process, grid(10, 10, 0.01), params)
        big = await configure_times("DET", process, grid(100, 100, 0.01), params)
        runs = []
        for _ in range(3):
            generator = grid(40, POINTS // 40, EXPOSURE)
            await process.post(["DET", "configure"], {"generator": generator, **params})
            began = time.perf_counter()
            await process.post(["DET", "run"])
            runs.append(time.perf_counter() - began)
        overhead = median(runs)
    finally:
        await process.stop()
    return small, big, overhead


async def demo() -> tuple[float, float]:
    from malcolm.demo import demo_process

    process = demo_process()
    await process.start()
    try:
        small = await configure_times("SCAN", process, grid(10, 10, 0.01), {})
        big = await configure_times("SCAN", process, grid(100, 100, 0.01), {})
    finally:
        await process.stop()
    return small, big


def raw_run(file_dir: str, points: int) -> float:
    """Seconds the same acquisition takes driven by raw pyepics puts: the
    plugin loaded and started, the writer capturing, then Acquire."""
    import epics

    from malcolm.parts.adcore import positions_xml
    from malcolm.parts.detector_manager import XML_BATCH

    def put(pv: str, value: Any, wait: bool = True) -> None:
        epics.caput(f"{PREFIX}:{pv}", value, wait=wait)

    for pv, value in (
        ("CAM:Exposure", EXPOSURE),
        ("CAM:AcquirePeriod", EXPOSURE),
        ("CAM:ImageMode", 1),
        ("CAM:TriggerMode", 0),
        ("CAM:NumImages", points),
        ("POS:Delete", 1),
        ("POS:IDStart", 1),
        ("POS:EnableCallbacks", 1),
        ("HDF:FilePath", file_dir + "/"),
        ("HDF:FileName", "raw"),
        ("HDF:NumCapture", points),
        ("HDF:Append", 0),
        ("HDF:LazyOpen", 0),
        ("HDF:EnableCallbacks", 1),
    ):
        put(pv, value)
    for start in range(0, points, XML_BATCH):
        put("POS:Filename", positions_xml(start, min(points, start + XML_BATCH)))
    put("POS:Running", 1, wait=False)
    put("HDF:Capture", 1, wait=False)
    while not (
        epics.caget(f"{PREFIX}:POS:Running_RBV")
        and epics.caget(f"{PREFIX}:HDF:Capture_RBV")
    ):
        time.sleep(0.001)
    began = time.perf_counter()
    put("CAM:Acquire", 1)
    while epics.caget(f"{PREFIX}:HDF:Capture_RBV"):
        time.sleep(0.0005)
    return time.perf_counter() - began


def main() -> None:
    from malcolm.sim.beamline_ioc import SimIOC, ca_environment

    os.environ.update(ca_environment())
    ioc = SimIOC(PREFIX)
    ioc.start()
    try:
        with tempfile.TemporaryDirectory() as tmp:
            raw = median([raw_run(tmp, POINTS) for _ in range(3)])
            small, big, ours = asyncio.run(detector(tmp))
            raw_small = raw_configure_times(tmp, 100)
            raw_big = raw_configure_times(tmp, 10_000)
    finally:
        ioc.stop()
    demo_small, demo_big = asyncio.run(demo())
    ms = 1e3
    rows = [
        Row(
            "configure 10x10, DetectorManager / demo SCAN",
            small / demo_small,
            "x",
            "<= 3x (hierarchy)",
            "30 ms (2 layers)",
            f"detector {small * ms:.1f} ms, demo {demo_small * ms:.1f} ms",
        ),
        Row(
            "configure 10,000 points, DetectorManager / demo SCAN",
            big / demo_big,
            "x",
            "<= 3x (hierarchy)",
            "-",
            f"detector {big * ms:.1f} ms, demo {demo_big * ms:.1f} ms",
        ),
        Row(
            "configure 10x10, DetectorManager / raw library (floor)",
            small / raw_small,
            "x",
            "-",
            "-",
            f"detector {small * ms:.1f} ms, raw {raw_small * ms:.1f} ms",
        ),
        Row(
            "configure 10,000 points, DetectorManager / raw library (floor)",
            big / raw_big,
            "x",
            "-",
            "-",
            f"detector {big * ms:.1f} ms, raw {raw_big * ms:.1f} ms",
        ),
        Row(
            f"run at {EXPOSURE * ms:g} ms exposure, DetectorManager - raw pyepics",
            (ours - raw) / POINTS * ms,
            "ms/pt",
            "<= 0.1 ms/pt",
            "-",
            f"{POINTS} points into HDF5: run {ours:.3f} s, raw {raw:.3f} s"
            f" ({ours / raw:.2f}x; exposures alone {POINTS * EXPOSURE:.3f} s)",
        ),
    ]
    print(render(rows, "targets: issue 13"))


if __name__ == "__main__":
    main()

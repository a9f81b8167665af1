"""Issue 13's benchmark: the whole hierarchy beside the demo's single layer.

    ../shared/tools/isolated .venv/bin/python -m benchmarks.beamline \
        [--points 1000] [--repeats 5]

Runs the simulated IOC and Zebra2 as subprocesses (as ``malcolm beamline``
does) and builds the beamline process (``malcolm/blocks/beamline/
process.yaml``: three device managers and the BeamlineManager ``BENCH:SCAN``)
in this process, then measures, each beside the same figure for the demo's
single-layer ``SCAN`` (two simulated detectors, two motors) in a process of
its own:

- configure of a 10x10 snake grid and of a 10,000-point spiral (median of
  ``--repeats``, each a slightly different scan so none finds its points
  kept; the block reset between), target: the three layers within 3x the
  single layer;
- the overhead per point of a run of a ``--points`` grid at the smallest
  exposure the hierarchy accepts (its ``validate`` raises what is too
  short): (run time - the motion's own time) / points, the run alone (after
  configure), target: at most 0.1 ms a point more than the demo's at the
  same exposure. The motion's own time is the trajectory's profile (the
  points, the run-up and the snake's turnarounds, each taking the motors'
  acceleration time: 0.2 s a row at the simulated motors' 0.1 s ACCL, about
  6 ms a point of a 32-point row, which is the motors', not malcolm's); the
  demo's motors have none, so its figure is (run time - points x
  exposure) / points. The figure with the run-up and turnarounds left in
  (run time - points x exposure) / points is printed below it. The same
  for a 10,000-point spiral (points back to back, no turnarounds: the
  sustained per-point work, against the demo's same spiral).

Beside each, the slowest device manager's figure alone (configured and run
without the BeamlineManager), and the three device managers configured at
once without it, alternated with the 3 layers' configure of the same scan
(the reference column): they share this process's loop (and two cores
with the simulations), so their work adds up; the 3 layers minus that
figure is the co-ordination layer's own share.

And the floor: the three devices' configure traffic done by the raw
libraries at once, with no framework (:mod:`benchmarks.raw_ca` for the
detector's and the motion controller's Channel Access, with their files;
:class:`benchmarks.zebramgr.RawBox` for the Zebra's setup, data connection,
file and ARM), the same scans as the three devices at once, against a new
simulated IOC and Zebra2 with no malcolm process running (whose monitors
would share this process's CPU). The simulations' own latency is in it: it
is what any framework pays with this simulated hardware.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import math
import os
import sys
import tempfile
import time
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

from benchmarks.table import Row, median, render
from malcolm.scan import gda

PREFIX = "BENCH"
SCAN = f"{PREFIX}:SCAN"
DEVICES = [f"{PREFIX}:{name}" for name in ("DET", "MOTORS", "ZEBRA")]
MOTORS = f"{PREFIX}:MOTORS"
ZEBRA = f"{PREFIX}:ZEBRA"
#: the floor's IOC (new PV names: CA would take seconds to find the first
#: IOC's names again on a new IOC, without a CA repeater)
FLOOR = "BENCHFLOOR"
#: points of the spiral run back to back (no turnarounds)
SPIRAL_RUN = 10_000
SOURCE = "targets from issue 13; reference: the demo's single-layer SCAN"


def grid(ny: int, nx: int, duration: float) -> dict[str, Any]:
    """A snake grid with points 0.01 apart (slow enough for the motors at
    the smallest exposure)."""
    return gda.compound(
        gda.line("y", ny, 0.0, 0.01 * (ny - 1)),
        gda.line("x", nx, 0.0, 0.01 * (nx - 1), alternate=True),
        duration=duration,
    )


def spiral(points: int, duration: float) -> dict[str, Any]:
    """A spiral of about ``points`` points, rings 0.01 apart."""
    radius = 0.01 * math.sqrt((points - 0.5) / math.pi)
    return gda.compound(gda.spiral("x", "y", radius, scale=0.01), duration=duration)


def log(text: str) -> None:
    """Progress on stderr (the table goes to stdout at the end)."""
    print(f"benchmarks.beamline: {text}", file=sys.stderr, flush=True)


async def configure_time(
    process: Any, mri: str, generator: dict[str, Any], **args: Any
) -> float:
    """Seconds one configure takes; the block is reset after."""
    start = time.perf_counter()
    await process.post(
        [mri, "configure"], {"generator": generator, "axesToMove": ["x", "y"], **args}
    )
    took = time.perf_counter() - start
    await process.post([mri, "reset"])
    log(f"{mri} configure {took * 1e3:.3g} ms")
    return took


def motion_time(process: Any, points: int, exposure: float) -> float:
    """Seconds the configured run's motion must take: the trajectory's
    profile (run-up, the points, the snake's turnarounds at the motors'
    acceleration time) when the hierarchy has a motion controller, else
    ``points`` x ``exposure`` (the demo's motors and the Zebra alone wait for
    nothing else)."""
    try:
        part = process.get_controller(MOTORS).parts["trajectory"]
    except (KeyError, LookupError):
        return points * exposure
    profile = part.profile
    if profile is None:
        return points * exposure
    return float(profile.times.sum()) / 1e6


async def run_time(
    process: Any, mri: str, generator: dict[str, Any], exposure: float, **args: Any
) -> tuple[float, float, int]:
    """Seconds the runs of a configured scan take, to Finished, the seconds
    its motion must take (:func:`motion_time`; the scan is one run) and its
    points."""
    await process.post(
        [mri, "configure"], {"generator": generator, "axesToMove": ["x", "y"], **args}
    )
    points = int(process.get([mri, "totalSteps", "value"]))
    needed = motion_time(process, points, exposure) if mri != ZEBRA else 0.0
    needed = needed or points * exposure
    start = time.perf_counter()
    while process.get([mri, "state", "value"]) != "Finished":
        await process.post([mri, "run"])
    took = time.perf_counter() - start
    await process.post([mri, "reset"])
    log(f"{mri} run {took:.3g} s (its motion {needed:.3g} s)")
    return took, needed, points


async def measure_layers(
    process: Any,
    mri: str,
    points: int,
    repeats: int,
    exposure: float,
    runs: bool = True,
    sustained: bool = False,
    **args: Any,
) -> dict[str, float]:
    """Configure times of the grid and the spiral; with ``runs``, the
    overhead per point of a run of a ``points`` grid."""
    out: dict[str, float] = {}
    # first configures import and warm up what a scan uses: not counted
    await configure_time(process, mri, grid(10, 10, 0.5), **args)
    out["grid"] = median(
        [
            await configure_time(process, mri, grid(10, 10, 0.1 + i * 1e-6), **args)
            for i in range(repeats)
        ]
    )
    out["spiral"] = median(
        [
            await configure_time(process, mri, spiral(10_000, 0.1 + i * 1e-6), **args)
            for i in range(repeats)
        ]
    )
    if not runs:
        return out
    ny = max(1, int(math.sqrt(points)))
    nx = max(1, points // ny)
    n = ny * nx
    timed = [
        await run_time(
            process, mri, grid(ny, nx, exposure * (1 + i * 1e-6)), exposure, **args
        )
        for i in range(max(1, repeats // 2))
    ]
    took = median([t for t, _, _ in timed])
    needed = median([m for _, m, _ in timed])
    # beyond the motion's own time (its run-up and turnarounds are the
    # motors' acceleration, not per-point work) ...
    out["overhead"] = (took - needed) / n
    # ... and beyond points x exposure alone (what the formula gives)
    out["raw"] = (took - n * exposure) / n
    out["points"] = n
    if sustained:
        # the points back to back (a spiral: no turnarounds), the same size
        timed = [
            await run_time(
                process, mri, spiral(SPIRAL_RUN, exposure * (1 + i * 1e-6)),
                exposure, **args,
            )
            for i in range(max(1, repeats // 2))
        ]  # fmt: skip
        took = median([t for t, _, _ in timed])
        needed = median([m for _, m, _ in timed])
        out["sustained"] = (took - needed) / timed[0][2]
        out["sustained_points"] = timed[0][2]
    return out


async def configure_devices_time(
    process: Any, generator: dict[str, Any], **args: Any
) -> float:
    """Seconds the three device managers take configured at once, without
    the BeamlineManager (each its own raw file, as the beamline names them);
    they are reset after."""
    scan = args.pop("formatName", "bench")

    async def configure(mri: str) -> None:
        name = f"{scan}-{mri.rsplit(':', 1)[-1].lower()}"
        await process.post(
            [mri, "configure"],
            {"generator": generator, "axesToMove": ["x", "y"], **args,
             "formatName": name},
        )  # fmt: skip

    start = time.perf_counter()
    await asyncio.gather(*(configure(mri) for mri in DEVICES))
    took = time.perf_counter() - start
    await asyncio.gather(*(process.post([mri, "reset"]) for mri in DEVICES))
    log(f"the three devices at once: configure {took * 1e3:.3g} ms")
    return took


#: the scans of the three devices at once (and of the floor), by shape
AT_ONCE = {
    "grid": lambda i: grid(10, 10, 0.2 + i * 1e-6),
    "spiral": lambda i: spiral(10_000, 0.2 + i * 1e-6),
}


async def measure_devices_at_once(
    process: Any, repeats: int, **args: Any
) -> dict[str, float]:
    """Configure times of the grid and the spiral, the three devices at once
    (what the beamline's Configure phase does, without the beamline), each
    alternated with the beamline's configure of the same scan, so that both
    see the machine's load of the moment: ``<shape>`` the devices',
    ``<shape>_beamline`` the beamline's beside them."""
    await configure_devices_time(process, grid(10, 10, 0.5), **args)
    out: dict[str, float] = {}
    for shape, make in AT_ONCE.items():
        devices, beamline = [], []
        for i in range(repeats):
            devices.append(await configure_devices_time(process, make(i), **args))
            beamline.append(await configure_time(process, SCAN, make(i), **args))
        out[shape] = median(devices)
        out[f"{shape}_beamline"] = median(beamline)
    return out


async def smallest_exposure(process: Any, mri: str, want: float) -> float:
    """The exposure the hierarchy's validate gives back for ``want`` (a scan
    of one point: no motor speed to refuse at any duration)."""
    validated = await process.post(
        [mri, "validate"], {"generator": grid(1, 1, want), "axesToMove": ["x", "y"]}
    )
    return float(validated["generator"]["duration"])


@contextlib.asynccontextmanager
async def beamline_process(
    process_file: Path | None = None,
) -> AsyncIterator[Any]:
    """The simulated IOC and Zebra2 as subprocesses and the beamline process
    (``process_file``, default :data:`BEAMLINE_PROCESS_FILE` or
    ``$BEAMLINE_PROCESS``) started in this one, as ``malcolm beamline``
    does; all stopped after."""
    from malcolm.beamline import (
        BEAMLINE_PROCESS_FILE,
        SimZebra2,
        beamline_defines,
        build_beamline,
    )
    from malcolm.sim.beamline_ioc import SimIOC

    if process_file is None:
        process_file = Path(os.environ.get("BEAMLINE_PROCESS", BEAMLINE_PROCESS_FILE))
    ioc = SimIOC(PREFIX)
    zebra = SimZebra2()
    ioc.start()
    try:
        zebra.start()
        process = build_beamline(process_file, beamline_defines(PREFIX, zebra, ""))
        await process.start()
        try:
            yield process
        finally:
            await process.stop()
    finally:
        zebra.stop()
        ioc.stop()


async def beamline_figures(points: int, repeats: int, want: float) -> dict[str, Any]:
    async with beamline_process() as process:
        with tempfile.TemporaryDirectory() as file_dir:
            exposure = await smallest_exposure(process, SCAN, want)
            figures = await measure_layers(
                process,
                SCAN,
                points,
                repeats,
                exposure,
                sustained=True,
                fileDir=file_dir,
            )
            # the detector triggered externally waits for the motion:
            # it has no run alone
            figures["devices"] = {
                mri: await measure_layers(
                    process,
                    mri,
                    points,
                    repeats,
                    exposure,
                    runs=not mri.endswith(":DET"),
                    fileDir=file_dir,
                )
                for mri in DEVICES
            }
            figures["at_once"] = await measure_devices_at_once(
                process, repeats, fileDir=file_dir
            )
            figures["profiles"] = await motion_profiles(process, repeats)
        figures["exposure"] = exposure
        return figures


async def motion_profiles(process: Any, repeats: int) -> dict[str, list[Any]]:
    """The MOTORS' profile of each scan of :data:`AT_ONCE` (configured alone,
    no file; reset after): what the floor's trajectory sends."""
    part = process.get_controller(MOTORS).parts["trajectory"]
    out: dict[str, list[Any]] = {}
    for shape, make in AT_ONCE.items():
        out[shape] = []
        for i in range(repeats):
            await process.post(
                [MOTORS, "configure"], {"generator": make(i), "axesToMove": ["x", "y"]}
            )
            out[shape].append(part.profile)
            await process.post([MOTORS, "reset"])
    return out


class Floor:
    """The three devices' configure traffic by the raw libraries, against
    simulators of their own (see the module's docstring)."""

    def __init__(self, raw: Any, box: Any, file_dir: str) -> None:
        self.raw, self.box, self.dir = raw, box, file_dir

    def detector(self, points: int, exposure: float, everything: bool) -> None:
        from benchmarks import raw_ca
        from malcolm.parts.adcore import positions_xml
        from malcolm.parts.detector_manager import XML_BATCH

        other, writer = raw_ca.detector_settings(
            FLOOR, exposure, points, self.dir, "raw-det", external=True
        )
        if not everything:  # what changed from the last scan: its duration
            other = {k: v for k, v in other.items() if "Exposure" in k or "Period" in k}
            writer = {}
        loaded = min(points, 10_000)  # the manager's preload
        batches = [
            positions_xml(start, min(loaded, start + XML_BATCH))
            for start in range(0, loaded, XML_BATCH)
        ]
        raw_ca.detector_configure(self.raw, FLOOR, other, writer, batches, True)

    def motion(self, arrays: dict[str, Any]) -> None:
        from benchmarks import raw_ca
        from malcolm.parts.motion_file import MotionFile

        made = MotionFile(f"{self.dir}/raw-motors.h5", ["x", "y"])
        raw_ca.motion_configure(self.raw, FLOOR, arrays, made.create)

    async def configure(
        self, points: int, exposure: float, arrays: dict[str, Any], everything: bool
    ) -> float:
        """Seconds the three take at once."""
        start = time.perf_counter()
        await asyncio.gather(
            asyncio.to_thread(self.detector, points, exposure, everything),
            asyncio.to_thread(self.motion, arrays),
            self.box.arm(points, exposure, Path(self.dir) / "raw-zebra.h5"),
        )
        took = time.perf_counter() - start
        from benchmarks import raw_ca

        await asyncio.to_thread(raw_ca.detector_stop, self.raw, FLOOR)
        await self.box.disarm()
        return took


async def floor_figures(profiles: dict[str, list[Any]]) -> dict[str, float]:
    """Median seconds of the floor's configure of each shape's scans."""
    import numpy as np

    from benchmarks import raw_ca
    from benchmarks.zebramgr import RawBox
    from malcolm.beamline import SimZebra2
    from malcolm.sim.beamline_ioc import SimIOC

    ioc = SimIOC(FLOOR)
    zebra = SimZebra2()
    ioc.start()
    try:
        zebra.start()
        box = RawBox(zebra.host, zebra.control_port, zebra.data_port)
        await box.open_control()
        names, monitored = raw_ca.detector_pvs(FLOOR)
        raw = raw_ca.RawCA(names + raw_ca.motion_pvs(FLOOR)[0], monitored)
        out: dict[str, float] = {}
        try:
            with tempfile.TemporaryDirectory() as file_dir:
                floor = Floor(raw, box, file_dir)
                for shape, made in profiles.items():
                    arrays = [raw_ca.motion_arrays(FLOOR, p) for p in made]
                    points = [int(p.stop_step) for p in made]
                    exposures = [
                        AT_ONCE[shape](i)["duration"] for i in range(len(made))
                    ]
                    # the first puts everything (not counted)
                    await floor.configure(points[-1], exposures[-1], arrays[-1], True)
                    times = []
                    for i in range(len(made)):
                        last = arrays[i - 1]
                        changed = {
                            pv: v
                            for pv, v in arrays[i].items()
                            if not np.array_equal(np.asarray(last[pv]), np.asarray(v))
                        }
                        took = await floor.configure(
                            points[i], exposures[i], changed, False
                        )
                        log(f"the floor: configure {took * 1e3:.3g} ms")
                        times.append(took)
                    out[shape] = median(times)
        finally:
            raw.close()
            box.writer.close()
        return out
    finally:
        zebra.stop()
        ioc.stop()


async def demo_figures(points: int, repeats: int, exposure: float) -> dict[str, Any]:
    from malcolm.demo import demo_process

    process = demo_process()
    await process.start()
    try:
        return await measure_layers(
            process, "SCAN", points, repeats, exposure, sustained=True
        )
    finally:
        await process.stop()


def rows(three: dict[str, Any], one: dict[str, Any]) -> list[Row]:
    ms = 1e3
    out = []
    for key, case in (("grid", "10x10 snake grid"), ("spiral", "10,000-point spiral")):
        ratio = three[key] / one[key]
        out.append(
            Row(
                f"configure {case}, 3 layers",
                three[key] * ms,
                "ms",
                f"<= 3x ({3 * one[key] * ms:.3g} ms)",
                f"{one[key] * ms:.3g} ms",
                f"{ratio:.2f}x the single layer",
            )
        )
    devices = three["devices"]
    for key, case in (("grid", "10x10 grid"), ("spiral", "10,000-point spiral")):
        slowest = max(devices, key=lambda mri: devices[mri][key])
        alone = devices[slowest][key]
        out.append(
            Row(
                f"  {case}: slowest device alone ({slowest})",
                alone * ms,
                "ms",
                "-",
                "-",
                f"the co-ordination layer adds {(three[key] - alone) * ms:.3g} ms",
            )
        )
    at_once = three["at_once"]
    for key, case in (("grid", "10x10 grid"), ("spiral", "10,000-point spiral")):
        beside = at_once[f"{key}_beamline"]
        out.append(
            Row(
                f"  {case}: the 3 devices at once, no beamline",
                at_once[key] * ms,
                "ms",
                "-",
                f"{beside * ms:.3g} ms",
                "the co-ordination layer's own share"
                f" {(beside - at_once[key]) * ms:.3g} ms (3 layers alternated)",
            )
        )
    floor = three["floor"]
    for key, case in (("grid", "10x10 grid"), ("spiral", "10,000-point spiral")):
        beside = at_once[f"{key}_beamline"]
        out.append(
            Row(
                f"  {case}: the 3 devices' traffic by the raw libraries at once",
                floor[key] * ms,
                "ms",
                f"<= 3x ({3 * one[key] * ms:.3g} ms)",
                f"{one[key] * ms:.3g} ms",
                f"the floor: {floor[key] / one[key]:.2f}x the single layer;"
                f" 3 layers {beside / floor[key]:.2f}x it",
            )
        )
    added = three["overhead"] - one["overhead"]
    out.append(
        Row(
            f"run overhead/point at {three['exposure'] * ms:g} ms, 3 layers",
            three["overhead"] * ms,
            "ms",
            "-",
            f"{one['overhead'] * ms:.3g} ms",
            f"{three['points']} points; run - the trajectory's time",
        )
    )
    out.append(
        Row(
            "  the same with the motion's run-up and turnarounds",
            three["raw"] * ms,
            "ms",
            "-",
            f"{one['raw'] * ms:.3g} ms",
            "run - points x exposure",
        )
    )
    out.append(
        Row(
            "  added by the 3 layers",
            added * ms,
            "ms",
            "<= 0.1 ms",
            "-",
            "3 layers - single layer",
        )
    )
    sustained = three["sustained"] - one["sustained"]
    out.append(
        Row(
            f"run overhead/point, {three['sustained_points']}-point spiral, 3 layers",
            three["sustained"] * ms,
            "ms",
            "-",
            f"{one['sustained'] * ms:.3g} ms",
            "points back to back; run - the trajectory's time",
        )
    )
    out.append(
        Row(
            "  added by the 3 layers",
            sustained * ms,
            "ms",
            "<= 0.1 ms",
            "-",
            "3 layers - single layer",
        )
    )
    ran = [mri for mri in devices if "overhead" in devices[mri]]
    slowest = max(ran, key=lambda mri: devices[mri]["overhead"])
    alone = devices[slowest]["overhead"]
    out.append(
        Row(
            f"  slowest device's run alone ({slowest})",
            alone * ms,
            "ms",
            "-",
            "-",
            f"the co-ordination layer adds {(three['overhead'] - alone) * ms:.3g} ms",
        )
    )
    return out


async def measure(points: int, repeats: int, want: float) -> list[Row]:
    three = await beamline_figures(points, repeats, want)
    three["floor"] = await floor_figures(three.pop("profiles"))
    one = await demo_figures(points, repeats, three["exposure"])
    return rows(three, one)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=1000)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument(
        "--exposure",
        type=float,
        default=1e-6,
        help="exposure asked of validate, which raises it to the smallest the"
        " simulation sustains (default 1 us: that smallest)",
    )
    args = parser.parse_args(argv)
    from malcolm.sim.beamline_ioc import ca_environment

    os.environ.update(ca_environment())  # before pyepics makes its context
    print(
        render(asyncio.run(measure(args.points, args.repeats, args.exposure)), SOURCE)
    )


if __name__ == "__main__":
    main()

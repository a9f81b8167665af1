"""Issue 13's acceptance, as GDA drives the beamline over pvAccess (p4p):
``malcolm beamline`` serving the simulated IOC and Zebra2 through three
layers. Read the BeamlineManager's meta, state, simultaneousAxes and
configure's defaults; validate and configure a spiral and a snaking grid;
run; pause half way, seek back, resume; finish: the scan's file has one
frame per point, positions within tolerance of the scan's points, nothing
duplicated or missing at the pause. Kill the IOC mid-run: Fault naming the
child; restart it, reset: Ready, and a new scan runs."""

from __future__ import annotations

import os
import queue
import signal
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import h5py
import numpy as np
import pytest
from p4p import Type, Value
from p4p.client.thread import RemoteError

from malcolm.io.pva.convert import to_dict
from malcolm.scan import scan_points

from ..p4p_monitor import monitor
from .conftest import SCAN, Beamline, alive

SPG = "scanpointgenerator:generator"
LINE = Type(
    [("axes", "as"), ("units", "as"), ("start", "ad"), ("stop", "ad"),
     ("size", "i"), ("alternate", "?")],
    id=f"{SPG}/LineGenerator:1.0",
)  # fmt: skip
SPIRAL = Type(
    [("axes", "as"), ("units", "as"), ("centre", "ad"), ("radius", "d"),
     ("scale", "d"), ("alternate", "?")],
    id=f"{SPG}/SpiralGenerator:1.0",
)  # fmt: skip
COMPOUND = Type(
    [("generators", "av"), ("excluders", "av"), ("mutators", "av"),
     ("duration", "d"), ("continuous", "?"), ("delay_after", "d")],
    id=f"{SPG}/CompoundGenerator:1.0",
)  # fmt: skip
DURATION = 0.05  # seconds a point: a pause half way lands mid-run on a busy machine
TOLERANCE = 0.05  # mm between a readback and its point


def line(axis: str, size: int, start: float, stop: float, snake: bool) -> Value:
    return Value(LINE, {"axes": [axis], "units": ["mm"], "start": [start],
                        "stop": [stop], "size": size, "alternate": snake})  # fmt: skip


def spiral(radius: float) -> Value:
    return Value(SPIRAL, {"axes": ["x", "y"], "units": ["mm", "mm"],
                          "centre": [0.0, 0.0], "radius": radius, "scale": 0.5,
                          "alternate": False})  # fmt: skip


def compound(*generators: Value) -> Value:
    return Value(COMPOUND, {"generators": list(generators), "excluders": [],
                            "mutators": [], "duration": DURATION,
                            "continuous": True, "delay_after": 0.0})  # fmt: skip


def scan_args(generator: Value, axes: list[str], name: str) -> Value:
    args = Type(
        [("generator", COMPOUND.aspy()), ("axesToMove", "as"), ("formatName", "s")],
        id="structure",
    )
    value = Value(args, {"axesToMove": axes, "formatName": name})
    value["generator"] = generator
    return value


def call(ctx: Any, method: str, args: Value | None = None, timeout: float = 120):
    """GDA's form: the block's channel, the method's name in the pvRequest."""
    request = Value(Type([("method", "s")]), {"method": method})
    return ctx.rpc(SCAN, args or Value(Type([]), {}), request=request,
                   timeout=timeout)  # fmt: skip


def pause_at(ctx: Any, step: int) -> Value:
    args = Value(Type([("lastGoodStep", "i")]), {"lastGoodStep": step})
    return call(ctx, "pause", args)


def state(ctx: Any) -> str:
    return ctx.get(f"{SCAN}.state", timeout=10)["value"]


def wait_state(ctx: Any, want: str, timeout: float = 60) -> None:
    deadline = time.monotonic() + timeout
    while (now := state(ctx)) != want:
        assert time.monotonic() < deadline, f"{SCAN} is {now}, not {want}"
        time.sleep(0.05)


def points_of(generator: Value) -> Any:
    return scan_points(to_dict(generator))


def check_file(beamline: Beamline, name: str, generator: Value) -> np.ndarray:
    """The scan's file holds one frame per point, each point's readbacks
    within tolerance of its position; returns the detector's raw uniqueIds."""
    points = points_of(generator)
    n = points.size
    with h5py.File(beamline.file_dir / f"{name}.nxs", "r") as f:
        assert f["/entry"].attrs["NX_class"] == "NXentry"
        uid = f["/entry/uniqueid"][()].reshape(-1)
        assert uid.tolist() == list(range(1, n + 1))  # nothing missing
        frames = f["/entry/det/data"]
        assert frames.shape[: len(points.shape)] == tuple(points.shape)
        # each frame is the one its point's trigger made (the simulated
        # detector's pixels hold that point's index + 1): none taken from
        # the motion's deceleration at a pause as a re-done point
        seen = np.asarray(frames[()]).reshape(n, -1)
        wrong = [i + 1 for i in range(n) if not (seen[i] == (i + 1) % 65536).all()]
        assert not wrong, f"frames at the wrong uniqueId: {wrong}"
        assert f["/entry/det"].attrs["NX_class"] == "NXdata"
        for axis in points.axes:
            want = np.concatenate(list(points.column("positions", axis)))
            demand = f[f"/entry/{axis}/value_set"][()].reshape(-1)
            assert demand == pytest.approx(want)
            readback = f[f"/entry/{axis}/value"][()].reshape(-1)
            assert np.abs(readback - want).max() < TOLERANCE, axis
        panda = f["/entry/zebra"]
        for name_ in panda:
            assert panda[name_].shape[: len(points.shape)] == tuple(points.shape)
    return raw_uids(beamline, name)


def raw_uids(beamline: Beamline, name: str) -> np.ndarray:
    """The uniqueIds of the detector's raw file's rows, in the order written
    (found where the detector manager's ``datasets`` says)."""
    table = beamline.context().get("BLT:DET.datasets", timeout=10)["value"]
    path = list(table["uniqueid"])[0]
    with h5py.File(beamline.file_dir / f"{name}-det.h5", "r") as f:
        return np.asarray(f[path][()]).reshape(-1)


def test_gda_reads(ctx):
    # Ready whatever an earlier test of the module left (any order): a
    # Finished scan (the others' end) is reset
    ready(ctx)
    if state(ctx) == "Finished":
        call(ctx, "reset")
    assert state(ctx) == "Ready"
    assert ctx.get(f"{SCAN}.health", timeout=10)["value"] == "OK"
    meta = ctx.get(f"{SCAN}.meta", timeout=10)
    assert meta.getID() == "malcolm:core/BlockMeta:1.0"
    assert {"configure", "validate", "run", "pause", "resume"} <= set(meta["fields"])
    axes = ctx.get(f"{SCAN}.simultaneousAxes", timeout=10)["value"]
    assert sorted(axes) == ["x", "y"]
    configure = ctx.get(f"{SCAN}.configure", timeout=10)
    defaults = to_dict(configure["meta.defaults"])
    assert defaults["fileTemplate"] == "%s.nxs"
    assert defaults["frameTimeout"] == 0.0  # the detector's own bound
    assert defaults["fileDir"]  # malcolm beamline --file-dir
    assert configure["meta.takes.required"] == ["generator"]
    datasets = ctx.get(f"{SCAN}.datasets", timeout=10)
    assert "uniqueid" in datasets["value"]


def wait_steps(ctx: Any, steps: int, timeout: float = 60) -> None:
    """Until the scan has done ``steps`` points (fails after ``timeout``)."""
    deadline = time.monotonic() + timeout
    while ctx.get(f"{SCAN}.completedSteps", timeout=10)["value"] < steps:
        assert time.monotonic() < deadline, f"{SCAN} did not reach step {steps}"
        time.sleep(0.02)


def ready(ctx: Any) -> None:
    """Back to where configure is allowed, whatever an earlier test left."""
    now = state(ctx)
    if now in ("Ready", "Finished"):
        return
    if now not in ("Fault", "Aborted", "Disabled"):
        call(ctx, "abort")
    call(ctx, "reset")
    assert state(ctx) == "Ready"


def run_with_pause(ctx: Any, generator: Value, axes: list[str], name: str) -> int:
    """Validate, configure, run; pause half way, seek back to a quarter,
    resume; to the end. Returns the step sought back to."""
    ready(ctx)
    validated = call(ctx, "validate", scan_args(generator, axes, name))
    assert to_dict(validated["generator"])["duration"] >= DURATION
    call(ctx, "configure", scan_args(generator, axes, name))
    assert state(ctx) == "Armed"
    total = ctx.get(f"{SCAN}.totalSteps", timeout=10)["value"]
    assert total == points_of(generator).size
    steps: queue.Queue[int] = queue.Queue()
    sub = monitor(ctx, f"{SCAN}.completedSteps", lambda v: steps.put(v["value"]))
    try:
        with ThreadPoolExecutor(1) as pool:
            running = pool.submit(call, ctx, "run")
            while steps.get(timeout=60) < total // 2:
                pass
            back = total // 4
            pause_at(ctx, back)
            wait_state(ctx, "Paused")
            assert ctx.get(f"{SCAN}.completedSteps", timeout=10)["value"] == back
            call(ctx, "resume")
            running.result(timeout=120)
    finally:
        sub.close()
    wait_state(ctx, "Finished")
    return back


def test_spiral_paused_sought_back_resumed(beamline, ctx):
    generator = compound(spiral(2.0))
    back = run_with_pause(ctx, generator, ["x", "y"], "spiral")
    det = check_file(beamline, "spiral", generator)
    n = points_of(generator).size
    # the raw frames: points after the seek done twice, the file's once
    assert sorted(set(det.tolist()) - {0}) == list(range(1, n + 1))
    assert len(det[det > back]) > n - back


def test_snake_grid_paused_sought_back_resumed(beamline, ctx):
    generator = compound(line("y", 6, 0, 1.5, False), line("x", 8, 0, 2.5, True))
    run_with_pause(ctx, generator, ["x", "y"], "grid")
    check_file(beamline, "grid", generator)


def test_ioc_killed_mid_run_faults_naming_the_child(beamline, ctx):
    generator = compound(line("y", 3, 0, 1, False), line("x", 20, 0, 2, True))
    ready(ctx)
    call(ctx, "configure", scan_args(generator, ["x", "y"], "killed"))
    ioc_pid = beamline.child_pids()["IOC"]
    with ThreadPoolExecutor(1) as pool:
        running = pool.submit(call, ctx, "run")
        wait_steps(ctx, 5)
        os.kill(ioc_pid, signal.SIGKILL)
        with pytest.raises(RemoteError):
            running.result(timeout=60)
    wait_state(ctx, "Fault", timeout=60)
    health = ctx.get(f"{SCAN}.health", timeout=10)["value"]
    assert health.split(":")[0] in ("DET", "MOTORS"), health
    assert alive(beamline.child_pids()["Zebra2"])
    check_fault_file(beamline, "killed", generator, health)
    beamline.restart_ioc()
    # the hardware blocks say when their channels are connected again
    hardware = ["DET:DRV", "DET:POS", "DET:HDF", "MOTORS:traj", "MOTORS:a", "MOTORS:b"]
    deadline = time.monotonic() + 60
    for mri in hardware:
        while ctx.get(f"BLT:{mri}.health", timeout=10)["value"] != "OK":
            assert time.monotonic() < deadline, f"BLT:{mri} not reconnected"
            time.sleep(0.1)
    call(ctx, "reset")
    assert state(ctx) == "Ready"
    small = compound(line("y", 2, 0, 1, False), line("x", 3, 0, 1, True))
    call(ctx, "configure", scan_args(small, ["x", "y"], "after"))
    call(ctx, "run")
    assert state(ctx) == "Finished"
    check_file(beamline, "after", small)


def test_frames_that_stop_coming_fault_naming_det_and_the_frame(beamline, ctx):
    """A second Channel Access client cuts the driver's array callbacks
    mid-run: the motion and the Zebra finish, no frame reaches the writer
    again, and the detector's frame timeout (its default: 3 x 0.05 s + 10 s)
    ends the scan in Fault naming DET and the frame; the file holds the
    points taken."""
    from malcolm.sim.beamline_ioc import ca_environment

    generator = compound(line("y", 3, 0, 1, False), line("x", 20, 0, 2, True))
    ready(ctx)
    call(ctx, "configure", scan_args(generator, ["x", "y"], "stalled"))
    cut = (
        "import epics; epics.caput('BLT:CAM:ArrayCallbacks', 0, wait=True,"
        " timeout=10) or exit(1)"
    )
    with ThreadPoolExecutor(1) as pool:
        running = pool.submit(call, ctx, "run")
        wait_steps(ctx, 5)
        subprocess.run(
            [sys.executable, "-c", cut],
            env={**os.environ, **ca_environment(beamline.ca_port)},
            check=True,
            timeout=30,
        )
        # a ceiling for "it happens": the bound is 10.15 s after the last frame
        with pytest.raises(RemoteError, match="no frame"):
            running.result(timeout=60)
    wait_state(ctx, "Fault", timeout=30)
    health = ctx.get(f"{SCAN}.health", timeout=10)["value"]
    assert health.startswith("DET: "), health
    assert "BLT:DET: no frame " in health and "within 10.15 s of frame " in health
    # the triggers came and the driver made the frames (all of them: it is
    # Idle), which did not reach the writer: not blamed on the triggers
    assert "; trigger mode External; the driver is " in health, health
    assert health.endswith(
        "frames since: its frames do not reach the writer (the driver's"
        " arrayCallbacks is off)"
    ), health
    check_fault_file(beamline, "stalled", generator, health)
    with h5py.File(beamline.file_dir / "stalled.nxs", "r") as f:
        assert "det" in f["/entry"]  # the IOC is alive: its raw file is read
    ready(ctx)  # reset: the next configure turns the callbacks on again


def check_fault_file(
    beamline: Beamline, name: str, generator: Value, health: str
) -> None:
    """The faulted scan's file is written from what the raw files hold: the
    points taken before the fault (at least the 5 seen) are in it, a raw
    file the lost IOC left unreadable is named in ``problems``."""
    path = beamline.file_dir / f"{name}.nxs"
    deadline = time.monotonic() + 60  # a ceiling for "it is written"
    while not path.exists():
        assert time.monotonic() < deadline, f"no {path} after the fault"
        time.sleep(0.1)
    n = points_of(generator).size
    with h5py.File(path, "r") as f:
        entry = f["/entry"]
        assert entry.attrs["fault"] == health
        uid = entry["uniqueid"][()].reshape(-1)
        taken = int((uid > 0).sum())
        assert uid[:5].tolist() == [1, 2, 3, 4, 5]  # the rows taken first
        assert 5 <= taken < n
        # the Zebra (still alive) wrote its rows of those points
        for dataset in entry["zebra"].values():
            assert dataset.shape[: len(points_of(generator).shape)] == tuple(
                points_of(generator).shape
            )
        problems = [str(p) for p in entry.attrs.get("problems", [])]
        if "det" in entry:
            frames = entry["det/data"][()].reshape(n, -1)
            got = [i for i in range(n) if uid[i] and frames[i].any()]
            assert got and all((frames[i] == i + 1).all() for i in got)
        else:  # the IOC's file, cut short, is named
            assert any(f"{name}-det.h5" in p for p in problems), problems


def test_a_bad_generator_is_refused_and_serving_goes_on(ctx):
    ready(ctx)
    bad = Value(COMPOUND, {"generators": [spiral(-1.0)], "duration": DURATION})
    with pytest.raises(RemoteError, match=r"BadValueError: .*radius"):
        call(ctx, "validate", scan_args(bad, ["x", "y"], "bad"))
    assert state(ctx) in ("Ready", "Finished")


def test_stopping_leaves_no_simulator_running(tmp_path):
    from .conftest import launch

    served = launch(tmp_path)
    pids = served.child_pids()
    assert set(pids) == {"IOC", "Zebra2"}
    assert all(alive(p) for p in pids.values())
    out = served.stop()
    assert served.proc.returncode == 0, out
    assert "malcolm beamline: stopped" in out
    assert not any(alive(p) for p in pids.values()), out


def test_validate_gives_back_the_detectors_shortest_frame(ctx):
    """A duration the simulated detector cannot keep pace with comes back
    from the beamline's validate raised to its shortest frame."""
    from malcolm.parts.detector_manager import MIN_EXPOSURE

    ready(ctx)
    before = state(ctx)  # Ready, or Finished after another test's scan
    # points 0.001 mm apart: slow enough for the motors at either duration
    # (the children validate at once: the motion checks the duration given)
    short = compound(line("y", 2, 0.0, 0.001, False), line("x", 3, 0.0, 0.002, True))
    short["duration"] = MIN_EXPOSURE / 10
    validated = call(ctx, "validate", scan_args(short, ["x", "y"], "short"))
    assert to_dict(validated["generator"])["duration"] == pytest.approx(MIN_EXPOSURE)
    assert state(ctx) == before  # validate changed nothing

"""MotionTrajectoryPart (``parts.MotionTrajectoryPart``): a motion controller
manager's scan over a ``pmac.TrajectoryScan`` child and two
``motor.MotorRecord`` children (``docs/devices.md``).

- **validate** refuses, naming the axis and its motor, a scan whose points
  need more than a motor's ``maxVelocity``, leave its limits, have no
  duration, or need more profile points than the controller holds;
- **configure** (and each later run, and a seek) builds the run's profile
  (:mod:`.motion_profile`: bounds, midpoints, run-up, turnarounds), moves
  the scan's motors to the run-up start at their velocity, writes the
  arrays and builds it (a build Failure fails with the BuildMessage); it
  creates the raw file (:mod:`.motion_file`) and fills ``datasets``;
- **run** executes the profile: progress from ``pointsScanned``; the
  readback of each point is the motor readback last received before
  ``pointsScanned`` passed the point's midpoint (one IOC's CA events arrive
  in order); rows go to the file, in a worker thread, when the run ends,
  pauses, fails or is aborted;
- **pause** aborts the profile; **seek** prepares the run from the new step;
  **abort** aborts the profile and stops the motors; **reset** waits (up
  to ``RECONNECT_WAIT`` s) for the children to be connected and fails,
  naming the one that is not.
"""

from __future__ import annotations

import asyncio
from typing import TYPE_CHECKING, Any

import numpy as np

from malcolm.core import BadValueError, MalcolmError, StringMeta
from malcolm.fsm import RunnableDevice
from malcolm.io.channel import ChannelError

from .base import Part, PartRegistrar
from .motion_file import MotionFile, datasets_meta, datasets_rows
from .motion_profile import Profile, ProfileError, build_profile, too_fast

if TYPE_CHECKING:
    from malcolm.hooks import Task

__all__ = ["MotionTrajectoryPart"]

#: seconds reset waits for the children to be connected
RECONNECT_WAIT = 10.0
#: seconds to wait for the last pointsScanned event after the execution ends
LAST_EVENT_WAIT = 5.0
#: steps of the scan checked at a time in validate
CHECK_CHUNK = 65536


class MotionTrajectoryPart(Part):
    """Runs a scan's axes ``axis_a``/``axis_b`` as a trajectory of the
    child ``trajectory`` moving the motor children ``motor_a``/``motor_b``
    (children named as in the definition: mri ``<block mri>:<name>``)."""

    def __init__(
        self,
        name: str = "trajectory",
        axis_a: str = "x",
        axis_b: str = "y",
        trajectory: str = "traj",
        motor_a: str = "a",
        motor_b: str = "b",
    ) -> None:
        super().__init__(name)
        if axis_a and axis_a == axis_b:
            raise ValueError(f"axis_a and axis_b are both {axis_a!r}")
        self._names = (trajectory, motor_a, motor_b)
        self._axis_names = (axis_a, axis_b)
        self.profile: Profile | None = None
        self.file: MotionFile | None = None
        #: (step, profile point) of each point reached, not yet written
        self._rows: list[tuple[int, int]] = []
        self._history: _History | None = None

    # ---- set up
    def setup(self, registrar: PartRegistrar) -> None:
        self.controller = registrar.controller
        mri = registrar.mri
        trajectory, motor_a, motor_b = self._names
        self.traj = f"{mri}:{trajectory}"
        #: scan axis -> (trajectory letter, motor mri)
        self.axes: dict[str, tuple[str, str]] = {}
        for axis, letter, motor in zip(self._axis_names, "AB", (motor_a, motor_b)):
            if axis:
                self.axes[axis] = (letter, f"{mri}:{motor}")
        registrar.add_configure_arg(
            "fileDir",
            StringMeta("Directory of the raw file ('': no file)"),
            default="",
        )
        registrar.add_configure_arg(
            "formatName",
            StringMeta("The raw file is <fileDir>/<formatName>.h5"),
            default=mri.split(":")[-1].lower(),
        )
        self.datasets = registrar.add_attribute(
            "datasets", datasets_meta(), datasets_rows("", [])
        )

    @RunnableDevice.Init
    async def init(self, task: Task, device: Any) -> None:
        self.controller.simultaneous_axes.set_value(list(self.axes))

    # ---- helpers
    def _value(self, mri: str, field: str) -> Any:
        return self.controller.process.get_block(mri)[field].value

    def _moved(self, points: Any) -> list[str]:
        """The scan's axes this controller moves (in the scan's order)."""
        if points is None:
            return []
        return [a for a in points.axes if a in self.axes]

    def _capacity(self) -> int:
        return len(self._value(self.traj, "positionsA"))

    def _where(self, axis: str) -> str:
        return f"{self.controller.mri}: axis {axis} ({self.axes[axis][1]})"

    # ---- validate
    @RunnableDevice.Validate
    async def validate(self, task: Task, device: Any) -> dict[str, Any]:
        points = device.points
        moved = self._moved(points)
        if not moved:
            return {}
        mri = self.controller.mri
        if not points.has_duration:
            raise BadValueError(
                f"{mri}: the scan gives no duration per point; a trajectory needs one"
            )
        axes_to_move = device.params.get("axesToMove")
        if axes_to_move is None:
            axes_to_move = [a for a in self.axes if a in points.axes] or None
        steps = points.steps_per_run(
            list(axes_to_move) if axes_to_move is not None else None
        )
        capacity = self._capacity()
        if 2 * steps + 1 > capacity:
            raise BadValueError(
                f"{mri}: a run of {steps} points needs {2 * steps + 1} or more"
                f" profile points; the controller holds {capacity}"
            )
        limits = {
            a: (
                self._value(self.axes[a][1], "maxVelocity"),
                self._value(self.axes[a][1], "lowLimit"),
                self._value(self.axes[a][1], "highLimit"),
            )
            for a in moved
        }
        await asyncio.to_thread(self._check_points, points, moved, limits)
        return {}

    def _check_points(
        self,
        points: Any,
        moved: list[str],
        limits: dict[str, tuple[float, float, float]],
    ) -> None:
        """Speeds and limits of every point (in a worker thread)."""
        for chunk in points.chunks(CHECK_CHUNK, axes=moved):
            for axis in moved:
                vmax, low, high = limits[axis]
                lower, upper = chunk.lower[axis], chunk.upper[axis]
                fast = too_fast(lower, upper, chunk.duration, vmax)
                if fast is not None:
                    step, speed = fast
                    raise BadValueError(
                        f"{self._where(axis)} needs {speed:.6g}/s at point"
                        f" {chunk.start + step}, more than its maximum velocity"
                        f" {vmax:.6g}/s"
                    )
                least = min(float(lower.min()), float(upper.min()))
                most = max(float(lower.max()), float(upper.max()))
                if least < low or most > high:
                    raise BadValueError(
                        f"{self._where(axis)}: the scan goes from {least:.6g} to"
                        f" {most:.6g}, outside its limits [{low:.6g}, {high:.6g}]"
                    )

    # ---- configure and prepare a run
    @RunnableDevice.Configure
    async def configure(self, task: Task, device: Any) -> None:
        self._rows = []
        self.profile = None
        moved = self._moved(device.points)
        file_dir = str(device.params.get("fileDir") or "")
        name = str(device.params.get("formatName") or "")
        self.file = None
        making = None
        filename = ""
        if file_dir and moved:
            filename = f"{name}.h5"
            self.file = MotionFile(f"{file_dir.rstrip('/')}/{filename}", moved)
            making = asyncio.ensure_future(asyncio.to_thread(self.file.create))
        try:
            await self._prepare(task, device, 0)
        finally:
            if making is not None:
                await making
        self.datasets.set_value(datasets_rows(filename, moved))

    @RunnableDevice.PostRunArmed
    async def next_run(self, task: Task, device: Any) -> None:
        await self._prepare(task, device, device.completedSteps)

    @RunnableDevice.Seek
    async def seek(self, task: Task, device: Any) -> None:
        await self._prepare(task, device, device.completedSteps)

    async def _prepare(self, task: Task, device: Any, start: int) -> None:
        """Build the profile of the run starting at ``start`` and load it."""
        points = device.points
        moved = self._moved(points)
        self.profile = None
        if not moved or start >= points.size:
            return
        stop = self.controller.next_configured(start)
        chunk = points.chunk(start, stop, moved)
        accel = max(float(self._value(self.axes[a][1], "acceleration")) for a in moved)
        velocity = {a: float(self._value(self.axes[a][1], "velocity")) for a in moved}
        try:
            profile = build_profile(
                start,
                chunk.lower,
                chunk.positions,
                chunk.upper,
                chunk.duration,
                accel,
                velocity,
                moved,
            )
        except ProfileError as e:
            raise BadValueError(f"{self.controller.mri}: {e}") from None
        capacity = self._capacity()
        if profile.size > capacity:
            raise BadValueError(
                f"{self.controller.mri}: steps {start}..{stop - 1} need"
                f" {profile.size} profile points; the controller holds {capacity}"
            )
        # the run-up: the scan's motors go to their start, at their velocity
        await task.put(
            {(self.axes[a][1], "position"): profile.run_up[a] for a in moved}
        )
        arrays: dict[Any, Any] = {}
        for axis, (letter, motor) in self.axes.items():
            if axis in profile.positions:
                where = profile.positions[axis]
            else:  # not in the scan: stays where it is
                where = np.full(profile.size, float(self._value(motor, "position")))
            arrays[(self.traj, f"positions{letter}")] = where
        arrays[(self.traj, "times")] = profile.times
        arrays[(self.traj, "pointIndices")] = profile.indices
        arrays[(self.traj, "numPoints")] = profile.size
        await task.put(arrays)
        await task.process.post([self.traj, "buildProfile"])
        self.profile = profile

    # ---- run
    @RunnableDevice.Run
    async def run(self, task: Task, device: Any) -> None:
        profile = self.profile
        if profile is None:
            return
        moved = list(profile.positions)
        state = {
            "entry": 0,
            "fresh": self._value(self.traj, "pointsScanned") == 0,
            "done": profile.start_step,
        }
        history = self._history = _History(
            {a: float(self._value(self.axes[a][1], "position")) for a in moved}
        )

        def on_rbv(attr: Any, axis: str) -> None:
            history.readback(axis, *_reading(attr))

        def on_scanned(attr: Any) -> None:
            stamp, value = _reading(attr)
            scanned = int(value)
            if scanned == 0:
                state["fresh"] = True
                state["entry"] = 0
                history.restart()
            elif state["fresh"]:
                history.scanned(stamp, scanned)
                self._take(task, profile, state, scanned)

        process = task.process
        subs = [
            process.subscribe([self.axes[a][1], "position"], _args(on_rbv, a), False)
            for a in moved
        ]
        subs.append(process.subscribe([self.traj, "pointsScanned"], on_scanned, False))
        failed = True
        try:
            await self._checked(process.post([self.traj, "executeProfile"]))
            await self._checked(
                task.wait_all(
                    task.when_matches((self.traj, "pointsScanned"), profile.size),
                    timeout=LAST_EVENT_WAIT,
                )
            )
            self._take(task, profile, state, profile.size)
            failed = False
        finally:
            for sub in subs:
                process.unsubscribe(sub)
            if not failed or not _cancelled():
                await self._flush()

    async def _checked(self, awaitable: Any) -> Any:
        """``awaitable``'s result; a lost channel raises an error naming what
        was lost (the channel's message names the PV)."""
        try:
            return await awaitable
        except ChannelError as e:
            lost = [m for m in self._children() if not self._healthy(m)]
            what = ", ".join(lost) or self.traj
            raise MalcolmError(f"lost {what}: {e}") from None

    def _take(
        self, task: Task, profile: Profile, state: dict[str, Any], scanned: int
    ) -> None:
        """Profile points ``state['entry'] .. scanned-1`` were reached."""
        first, stop = state["entry"], min(scanned, profile.size)
        if stop <= first:
            return
        points = profile.point_of[first:stop]
        for entry in np.flatnonzero(points >= 0) + first:
            self._rows.append((int(profile.point_of[entry]), int(entry)))
        state["entry"] = stop
        done = int(profile.done_after[stop - 1])
        if done > state["done"]:
            state["done"] = done
            task.report_progress(done)

    async def _flush(self) -> None:
        """Write the rows reached so far to the file (in a worker thread)."""
        rows, self._rows = self._rows, []
        profile, file, history = self.profile, self.file, self._history
        if file is None or profile is None or history is None or not rows:
            return
        steps = np.array([r[0] for r in rows], dtype=np.int64)
        entries = np.array([r[1] for r in rows], dtype=np.int64)
        offsets = steps - profile.start_step
        demands = {a: profile.demands[a][offsets] for a in file.axes}
        readbacks = history.readbacks(entries, file.axes)
        uid = (steps + 1).astype(np.int32)
        await asyncio.to_thread(file.append, uid, demands, readbacks)

    # ---- pause, abort, reset
    async def _stop_profile(self, task: Task) -> None:
        if self._value(self.traj, "executeState") == "Executing":
            await task.process.post([self.traj, "abortProfile"])

    @RunnableDevice.Pause
    async def pause(self, task: Task, device: Any) -> None:
        await self._stop_profile(task)
        await self._flush()

    @RunnableDevice.Abort
    async def abort(self, task: Task, device: Any) -> None:
        await self._stop_profile(task)
        moving = [
            task.process.post([motor, "stop"])
            for _, motor in self.axes.values()
            if not self._value(motor, "doneMoving")
        ]
        await asyncio.gather(*moving)
        await self._flush()

    def _children(self) -> list[str]:
        return [self.traj] + [motor for _, motor in self.axes.values()]

    def _healthy(self, mri: str) -> bool:
        return self._value(mri, "health") == "OK"

    @RunnableDevice.Reset
    async def reset(self, task: Task, device: Any) -> None:
        self._rows = []
        self.profile = None
        loop = asyncio.get_running_loop()
        deadline = loop.time() + RECONNECT_WAIT
        while True:
            lost = [m for m in self._children() if not self._healthy(m)]
            if not lost:
                return
            if loop.time() > deadline:
                raise MalcolmError(
                    "; ".join(f"{m}: {self._value(m, 'health')}" for m in lost)
                )
            await asyncio.sleep(0.05)


class _History:
    """The IOC time stamps of an execution's readbacks and of its progress,
    so that a point's readback is the last one the IOC made before it made
    ``pointsScanned`` pass the point, however CA delivered or merged them."""

    def __init__(self, start: dict[str, float]) -> None:
        self.start = dict(start)
        self.restart()

    def restart(self) -> None:
        self.rbv: dict[str, tuple[list[float], list[float]]] = {
            a: ([float("-inf")], [v]) for a, v in self.start.items()
        }
        self.progress: tuple[list[float], list[int]] = ([], [])

    def readback(self, axis: str, stamp: float, value: Any) -> None:
        stamps, values = self.rbv[axis]
        stamps.append(stamp)
        values.append(float(value))

    def scanned(self, stamp: float, value: int) -> None:
        self.progress[0].append(stamp)
        self.progress[1].append(value)

    def readbacks(self, entries: np.ndarray, axes: list[str]) -> dict[str, np.ndarray]:
        """Each axis's readback when profile points ``entries`` were reached."""
        stamps, counts = (np.asarray(x) for x in self.progress)
        order = np.argsort(stamps, kind="stable")
        stamps, counts = stamps[order], np.maximum.accumulate(counts[order])
        if len(counts):
            at = np.minimum(
                np.searchsorted(counts, entries + 1, "left"), len(counts) - 1
            )
            when = stamps[at]
        else:
            when = np.full(len(entries), np.inf)
        out = {}
        for axis in axes:
            rbv_stamps, values = (np.asarray(x) for x in self.rbv[axis])
            order = np.argsort(rbv_stamps, kind="stable")
            rbv_stamps, values = rbv_stamps[order], values[order]
            out[axis] = values[np.searchsorted(rbv_stamps, when, "right") - 1]
        return out


def _reading(attr: Any) -> tuple[float, Any]:
    """(IOC time stamp in seconds, value) of an attribute as subscribed."""
    stamp = attr["timeStamp"]
    return stamp["secondsPastEpoch"] + stamp["nanoseconds"] * 1e-9, attr["value"]


def _args(func: Any, *args: Any) -> Any:
    return lambda value: func(value, *args)


def _cancelled() -> bool:
    task = asyncio.current_task()
    return task is not None and bool(task.cancelling())

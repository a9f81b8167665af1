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
- **run** executes the profile: progress from ``pointsScanned``; once the
  execution ends (or is stopped by a pause or an abort) the IOC posts the
  motors' readbacks at each profile point reached (``readbacksA``/``B``),
  and a row per point reached goes to the file (in a worker thread): its
  demand and the readback at its midpoint;
- **pause** aborts the profile; **seek** prepares the run from the new step;
  **abort** aborts the profile and stops the motors; **reset** waits (up
  to ``RECONNECT_WAIT`` s) for the children to be connected and fails,
  naming the one that is not.
"""

from __future__ import annotations

import asyncio
from typing import TYPE_CHECKING, Any

from malcolm.core import AlarmSeverity, BadValueError, MalcolmError, StringMeta
from malcolm.fsm import RunnableDevice
from malcolm.io.channel import ChannelError

from .base import Part, PartRegistrar
from .datasets import check_file_args
from .motion_file import MotionFile, datasets_meta, datasets_rows

if TYPE_CHECKING:
    from malcolm.hooks import Task

    from .motion_profile import Profile

# numpy and the profile maths load when first used: building blocks (the
# demo's included) imports this module, and must not import numpy

__all__ = ["MotionTrajectoryPart"]

#: seconds reset waits for the children to be connected
RECONNECT_WAIT = 10.0
#: seconds to wait for the last pointsScanned event after the execution ends
LAST_EVENT_WAIT = 5.0
#: seconds between two progress reports (completedSteps) during a run
PROGRESS_PERIOD = 0.01
#: steps of the scan checked at a time in validate
CHECK_CHUNK = 65536
#: a scan (or run) of at most this many steps is checked, and its profile
#: computed, on the loop (well under a millisecond: less than the hop to a
#: worker thread and back); a bigger one in a worker thread
CHECK_ON_LOOP = 1000


class MotionTrajectoryPart(Part):
    """Runs a scan's axes ``axis_a``/``axis_b`` as a trajectory of the
    child ``trajectory`` moving the motor children ``motor_a``/``motor_b``
    (children named as in the definition: mri ``<block mri>:<name>``);
    ``max_points`` is the length of the controller's arrays."""

    def __init__(
        self,
        name: str = "trajectory",
        axis_a: str = "x",
        axis_b: str = "y",
        trajectory: str = "traj",
        motor_a: str = "a",
        motor_b: str = "b",
        max_points: int = 50_000,
    ) -> None:
        super().__init__(name)
        if int(max_points) < 3:
            raise ValueError(f"max_points must be at least 3, not {max_points}")
        self.max_points = int(max_points)
        if axis_a and axis_a == axis_b:
            raise ValueError(f"axis_a and axis_b are both {axis_a!r}")
        self._names = (trajectory, motor_a, motor_b)
        self._axis_names = (axis_a, axis_b)
        self.profile: Profile | None = None
        self.file: MotionFile | None = None
        #: the profile last executed and the time stamps of the readbacks
        #: before it, until its rows are written
        self._executed: tuple[Profile, dict[str, float]] | None = None
        #: (scan content, axes, limits) of the last scan validate passed
        self._checked_ok: Any = None
        #: the last chunk the check of a scan computed, by the scan's content,
        #: its steps and axes: the profile of the scan's run takes it again
        self._checked_chunk: tuple[Any, Any] | None = None
        #: trajectory field -> (its time stamp, the array it holds), for the
        #: arrays sent (or found there) last
        self._sent: dict[str, tuple[float, Any]] = {}

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

    def _already_at(self, motor: str, target: float) -> bool:
        """Whether ``motor`` is still and within its retry deadband (RDBD,
        ``deadband``) of ``target``: a motor record would not move there, so
        no put is made."""
        block = self.controller.process.get_block(motor)
        if "deadband" not in block or not block["doneMoving"].value:
            return False
        position, deadband = block["position"].value, block["deadband"].value
        if position is None or deadband is None:
            return False
        return abs(float(position) - float(target)) <= float(deadband)

    def _holds(self, field: str, value: Any) -> bool:
        """Whether the trajectory child's ``field`` (kept up to date by its
        channel) holds ``value`` already, element for element. An array
        this part sent is remembered with the IOC's time stamp of it: while
        the field shows that time stamp (and its first, middle and last
        values), comparing with what was sent (numpy) is enough; otherwise
        the field's value is compared whole."""
        import numpy as np

        attr = self.controller.process.get_block(self.traj)[field]
        if attr.alarm.severity >= AlarmSeverity.INVALID_ALARM:  # not connected
            return False
        now = attr.value
        if not isinstance(value, np.ndarray):
            return bool(now == value)
        if now is None or len(now) != len(value):
            return False
        if not len(value):
            return True
        sent = self._sent.get(field)
        ends = (0, len(value) // 2, len(value) - 1)
        if (
            sent is not None
            and sent[0] == attr.timeStamp.to_time()
            and all(now[i] == sent[1][i] for i in ends)  # and a few values
        ):
            same = np.array_equal(sent[1], value)
        else:
            same = np.array_equal(np.asarray(now, dtype=value.dtype), value)
        if same:
            self._remember(field, value)
        return same

    def _remember(self, field: str, value: Any) -> None:
        """Note that the trajectory child's ``field`` holds array ``value``
        as of its time stamp now."""
        if hasattr(value, "dtype"):
            attr = self.controller.process.get_block(self.traj)[field]
            self._sent[field] = (attr.timeStamp.to_time(), value)

    def _capacity(self) -> int:
        return self.max_points

    def _where(self, axis: str) -> str:
        return f"{self.controller.mri}: axis {axis} ({self.axes[axis][1]})"

    # ---- validate
    @RunnableDevice.Validate
    async def validate(self, task: Task, device: Any) -> dict[str, Any]:
        mri = self.controller.mri
        check_file_args(
            mri,
            str(device.params.get("fileDir") or ""),
            str(device.params.get("formatName") or ""),
        )
        points = device.points
        moved = self._moved(points)
        if not moved:
            return {}
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
        # the same scan checked against the same limits passed already (a
        # beamline's validate, then its configure of this block)
        key = None
        if points.content is not None:
            key = (points.content, tuple(moved), tuple(limits.items()))
            if key == self._checked_ok:
                return {}
        if points.size <= CHECK_ON_LOOP:
            self._check_points(points, moved, limits)
        else:
            await asyncio.to_thread(self._check_points, points, moved, limits)
        self._checked_ok = key
        return {}

    def _check_points(
        self,
        points: Any,
        moved: list[str],
        limits: dict[str, tuple[float, float, float]],
    ) -> None:
        """Speeds and limits of every point (in a worker thread)."""
        from .motion_profile import too_fast

        for chunk in points.chunks(CHECK_CHUNK, axes=moved):
            if points.content is not None:
                key = (points.content, chunk.start, chunk.stop, tuple(moved))
                self._checked_chunk = (key, chunk)
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

    def _chunk(self, points: Any, start: int, stop: int, moved: list[str]) -> Any:
        """The points of steps ``start .. stop-1``: the chunk the scan's
        check computed, if it was these (a 10,000-point spiral's: 2.8 ms)."""
        kept = self._checked_chunk
        if kept is not None and points.content is not None:
            key, chunk = kept
            if key == (points.content, start, stop, tuple(moved)):
                return chunk
        return points.chunk(start, stop, moved)

    # ---- configure and prepare a run
    @RunnableDevice.Configure
    async def configure(self, task: Task, device: Any) -> None:
        self._executed = None
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
        import numpy as np

        from .motion_profile import ProfileError, build_profile

        points = device.points
        moved = self._moved(points)
        self.profile = None
        if not moved or start >= points.size:
            return
        stop = self.controller.next_configured(start)
        accel = max(float(self._value(self.axes[a][1], "acceleration")) for a in moved)
        velocity = {a: float(self._value(self.axes[a][1], "velocity")) for a in moved}

        def compute() -> Profile:
            chunk = self._chunk(points, start, stop, moved)
            return build_profile(
                start,
                chunk.lower,
                chunk.positions,
                chunk.upper,
                chunk.duration,
                accel,
                velocity,
                moved,
            )

        try:
            # a big run's profile (milliseconds of numpy) is computed in a
            # worker thread: the loop, and the other devices a beamline is
            # configuring at the same time, go on meanwhile
            if stop - start <= CHECK_ON_LOOP:
                profile = compute()
            else:
                profile = await asyncio.to_thread(compute)
        except ProfileError as e:
            raise BadValueError(f"{self.controller.mri}: {e}") from None
        capacity = self._capacity()
        if profile.size > capacity:
            raise BadValueError(
                f"{self.controller.mri}: steps {start}..{stop - 1} need"
                f" {profile.size} profile points; the controller holds {capacity}"
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
        # what the controller holds already (a scan configured again) is not
        # sent again: 20,001-point arrays cost the IOC and the client
        arrays = {k: v for k, v in arrays.items() if not self._holds(k[1], v)}

        async def load() -> None:
            for _, field in arrays:
                self._sent.pop(field, None)
            await task.put(arrays)
            for (_, field), value in arrays.items():
                self._remember(field, value)
            await task.process.post([self.traj, "buildProfile"])

        # the run-up move (the scan's motors to their start, at their
        # velocity) and the profile's loading and build at the same time;
        # a motor already there (within its deadband) is not moved
        run_up = {
            (self.axes[a][1], "position"): profile.run_up[a]
            for a in moved
            if not self._already_at(self.axes[a][1], profile.run_up[a])
        }
        jobs = [asyncio.ensure_future(task.put(run_up)), asyncio.ensure_future(load())]
        try:
            await asyncio.gather(*jobs)
        except BaseException:
            for job in jobs:
                job.cancel()
            raise
        self.profile = profile

    # ---- run
    @RunnableDevice.Run
    async def run(self, task: Task, device: Any) -> None:
        profile = self.profile
        if profile is None:
            return
        done_so_far = [profile.start_step]
        scanned_attr = self.controller.process.get_block(self.traj)["pointsScanned"]
        # what the IOC posts from this execution on is newer than these
        before = scanned_attr.timeStamp.to_time()
        self._executed = (profile, self._readback_stamps(profile))

        loop = asyncio.get_running_loop()
        reported = [loop.time()]

        def on_scanned(scanned: int) -> None:
            if scanned <= 0 or scanned_attr.timeStamp.to_time() <= before:
                return  # the last execution's count, or this one's start
            done = int(profile.done_after[min(scanned, profile.size) - 1])
            now = loop.time()
            # at most every PROGRESS_PERIOD, and the run's end at once
            if done > done_so_far[0] and (
                now - reported[0] >= PROGRESS_PERIOD or done == profile.stop_step
            ):
                done_so_far[0] = done
                reported[0] = now
                task.report_progress(done)

        sid = task.subscribe((self.traj, "pointsScanned"), on_scanned)
        try:
            await self._checked(task.process.post([self.traj, "executeProfile"]))
        finally:
            task.unsubscribe(sid)
        await self._checked(self._write_reached())

    async def _checked(self, awaitable: Any) -> Any:
        """``awaitable``'s result; a lost channel raises an error naming what
        was lost (the channel's message names the PV)."""
        try:
            return await awaitable
        except ChannelError as e:
            lost = [m for m in self._children() if not self._healthy(m)]
            what = ", ".join(lost) or self.traj
            raise MalcolmError(f"lost connection to {what}: {e}") from None

    def _readbacks(self, profile: Profile) -> dict[str, Any]:
        """Scan axis -> the trajectory's readbacks attribute of its axis."""
        block = self.controller.process.get_block(self.traj)
        return {a: block[f"readbacks{self.axes[a][0]}"] for a in profile.positions}

    def _readback_stamps(self, profile: Profile) -> dict[str, float]:
        return {
            a: attr.timeStamp.to_time() for a, attr in self._readbacks(profile).items()
        }

    async def _write_reached(self) -> None:
        """Once the IOC has posted the readbacks of the execution that ended,
        write a row per point it reached (in a worker thread)."""
        import numpy as np

        executed = self._executed
        if executed is None:
            return
        profile, before = executed
        attrs = self._readbacks(profile)
        loop = asyncio.get_running_loop()
        deadline = loop.time() + LAST_EVENT_WAIT
        while any(attrs[a].timeStamp.to_time() <= before[a] for a in attrs):
            if loop.time() > deadline:
                raise MalcolmError(
                    f"{self.traj}: no readbacks within {LAST_EVENT_WAIT} s of the"
                    " end of the execution"
                )
            await asyncio.sleep(0.005)
        values = {a: np.asarray(attr.value, dtype=float) for a, attr in attrs.items()}
        reached = min(len(v) for v in values.values())
        entries = np.flatnonzero(profile.point_of[:reached] >= 0)
        file = self.file
        self._executed = None  # from here on, written once even if cancelled
        if file is None or not len(entries):
            return
        steps = profile.point_of[entries].astype(np.int64)
        offsets = steps - profile.start_step
        demands = {a: profile.demands[a][offsets] for a in file.axes}
        readbacks = {a: values[a][entries] for a in file.axes}
        uid = (steps + 1).astype(np.int32)
        await asyncio.shield(asyncio.to_thread(file.append, uid, demands, readbacks))

    # ---- pause, abort, reset
    async def _stop_profile(self, task: Task) -> None:
        if self._value(self.traj, "executeState") == "Executing":
            await task.process.post([self.traj, "abortProfile"])

    @RunnableDevice.Pause
    async def pause(self, task: Task, device: Any) -> None:
        await self._stop_profile(task)
        await self._write_reached()

    @RunnableDevice.Disable
    async def disable(self, task: Task, device: Any) -> None:
        """Let go of the hardware: a profile executing is stopped."""
        self._executed = None
        self.profile = None
        if self._healthy(self.traj):
            await self._stop_profile(task)

    @RunnableDevice.Abort
    async def abort(self, task: Task, device: Any) -> None:
        """Stop the profile and the motors that can be reached (a child whose
        IOC is lost has nothing to stop), and write the points reached."""
        if not self._healthy(self.traj):
            self._executed = None  # its readbacks will not come
        else:
            await self._stop_profile(task)
        moving = [
            task.process.post([motor, "stop"])
            for _, motor in self.axes.values()
            if self._healthy(motor) and not self._value(motor, "doneMoving")
        ]
        await asyncio.gather(*moving)
        await self._write_reached()

    def _children(self) -> list[str]:
        return [self.traj] + [motor for _, motor in self.axes.values()]

    def _healthy(self, mri: str) -> bool:
        return self._value(mri, "health") == "OK"

    @RunnableDevice.Reset
    async def reset(self, task: Task, device: Any) -> None:
        self._executed = None
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

"""Simulated motors and a trajectory-scan controller.

A motor ``P:M1`` serves the motor record's fields as PVs ``P:M1:VAL`` (a
put completes when the move is done), ``:RBV``, ``:VELO``, ``:ACCL``,
``:DMOV``, ``:STOP`` (a put of 1 stops the move), ``:HLM``, ``:LLM`` (which
become ``VAL``'s drive limits), ``:VMAX`` (the fastest it may go, in mm/s),
``:RDBD`` (the retry deadband, mm) and ``:EGU``. A soft IOC cannot make
record fields, so ``:`` stands where a motor record has ``.``; the
``motor.MotorRecord`` definition takes the separator as a parameter.

A move follows a trapezoidal velocity profile as a motor record's does:
``ACCL`` seconds to reach ``VELO``, at ``VELO``, ``ACCL`` seconds to stop
(:mod:`.trapezoid`); a distance too short to reach ``VELO`` is a triangle,
``2 * sqrt(d / a)`` with ``a = VELO / ACCL``. A put to ``VAL`` within
``RDBD`` of the readback completes at once and moves nothing (``DMOV``
stays 1), as a motor record does not move to a target within its retry
deadband. :attr:`Motor.moves` counts the moves made.

The trajectory controller ``P:TRAJ:`` (after pmac's trajectory scan):
``PositionsA``/``PositionsB`` (double arrays), ``Times`` (a long array of
microseconds to reach each point from the last), ``PointIndices`` (a long
array: the scan point whose exposure starts at each profile point, -1 for
none; by default each profile point announces its own index),
``NumPoints``, ``BuildProfile`` (checks the arrays; ``BuildStatus_RBV``
says Success or Failure, ``BuildMessage_RBV`` why),
``ExecuteProfile`` (walks the built points in time, moving the motors of
axes A and B; a put completes at the end), ``ExecuteStatus_RBV``,
``ExecuteState_RBV`` (Done/Executing), ``PointsScanned_RBV`` (progress),
``ReadbacksA``/``ReadbacksB`` (each motor's RBV as each profile point was
reached, posted once an execution ends, aborted or not, before
``ExecuteState_RBV`` says Done: the motor module's trajectoryScan
``M1Readbacks`` after its ``ReadbackProfile``) and ``AbortProfile`` (the
axes decelerate: the profile points due within the axes' longest ``ACCL``
of the abort are still reached, their triggers too, as a controller's
position compare goes on firing while the motors stop; then the execution
ends with Failure).

It holds :attr:`Trajectory.MAX_POINTS` (50,000) profile points, enough for a
10,000-point scan (two profile points per scan point, plus the run-up and
turnarounds); arrays that large need ``EPICS_CA_MAX_ARRAY_BYTES`` above
EPICS' 16 kB default, which the IOC sets for itself (pyepics clients set it
too). Each time a profile point is reached the motors of A and B are placed
there, ``PointsScanned_RBV`` counts it, and :attr:`Trajectory.point_listeners`
are called with its ``PointIndices`` entry (if not -1): a detector in
External mode takes one frame per call, as a controller's position compare
would trigger it.

An execution keeps an absolute schedule: profile point k is due at the
execution's start plus the times up to k, so a late point is done at once
and lateness does not add up. ``PointsScanned_RBV`` and the motors' ``RBV``
are posted at most every :data:`~.pace.STATUS_PERIOD` while it runs (as a
controller's status poll shows its progress; :mod:`.pace`), and their
final values before ``ReadbacksA``/``B`` and ``ExecuteState_RBV``.
"""

from __future__ import annotations

import asyncio
import os
from collections.abc import Callable

import numpy as np
from softioc import builder

from .pace import Schedule, Throttled
from .trapezoid import move_time, moved_by

TICK = 0.01  # seconds between position updates of a move
#: the motors' retry deadband (mm): a target this close is not moved to
RDBD = 1e-4

#: bytes of the largest array the IOC serves (50,000 doubles and more)
MAX_ARRAY_BYTES = 1_000_000


class Motor:
    """A motor moving on a trapezoidal profile at VELO (ACCL seconds to
    reach it); a target within RDBD of where it is is not moved to."""

    def __init__(self, name: str, low: float = -100.0, high: float = 100.0) -> None:
        builder.SetDeviceName(name)
        self.rbv = builder.aIn("RBV", initial_value=0.0, EGU="mm", PREC=3)
        self.dmov = builder.longIn("DMOV", initial_value=1)
        self.velo = builder.aOut(
            "VELO", initial_value=10.0, EGU="mm/s", PREC=3, DRVL=0.001, DRVH=1000
        )
        self.accl = builder.aOut(
            "ACCL", initial_value=0.1, EGU="s", PREC=3, DRVL=0, DRVH=10
        )
        self.rdbd = builder.aOut(
            "RDBD", initial_value=RDBD, EGU="mm", PREC=6, DRVL=0, DRVH=10
        )
        self.val = builder.aOut(
            "VAL",
            initial_value=0.0,
            EGU="mm",
            PREC=3,
            DRVL=low,
            DRVH=high,
            on_update=self.move,
            blocking=True,
            always_update=True,
        )
        self.hlm = builder.aOut("HLM", initial_value=high, PREC=3, on_update=self._high)
        self.llm = builder.aOut("LLM", initial_value=low, PREC=3, on_update=self._low)
        self.stop = builder.longOut("STOP", initial_value=0, on_update=self._stop)
        self.vmax = builder.aOut(
            "VMAX", initial_value=1000.0, EGU="mm/s", PREC=3, DRVL=0, DRVH=1e6
        )
        builder.stringIn("EGU", initial_value="mm")
        self.stopped = False
        #: moves made (a target within the deadband makes none)
        self.moves = 0

    def _high(self, value: float) -> None:
        self.val.set_field("DRVH", repr(float(value)))

    def _low(self, value: float) -> None:
        self.val.set_field("DRVL", repr(float(value)))

    def _stop(self, value: int) -> None:
        if value:
            self.stopped = True

    async def move(self, target: float) -> None:
        """Move to ``target``; returns when done (or stopped), at once if
        ``target`` is within the deadband."""
        start = self.rbv.get()
        distance = target - start
        if abs(distance) <= self.rdbd.get():
            return
        self.moves += 1
        self.stopped = False
        self.dmov.set(0)
        try:
            velocity = max(self.velo.get(), 1e-6)
            accl = max(self.accl.get(), 0.0)
            loop = asyncio.get_running_loop()
            began = loop.time()
            duration = move_time(distance, velocity, accl)
            sign = 1.0 if distance > 0 else -1.0
            while not self.stopped:
                elapsed = loop.time() - began
                if elapsed >= duration:
                    self.rbv.set(target)
                    break
                along = moved_by(elapsed, distance, velocity, accl)
                self.rbv.set(start + sign * along)
                await asyncio.sleep(min(TICK, duration - elapsed))
        finally:
            self.dmov.set(1)

    def place(self, position: float) -> None:
        """Show ``position`` (a trajectory moving the motor)."""
        self.rbv.set(position)


class Trajectory:
    """pmac-like trajectory scan over two axes."""

    #: profile points it holds (each array's length)
    MAX_POINTS = 50_000

    def __init__(self, prefix: str, axes: dict[str, Motor]) -> None:
        # arrays above EPICS' default 16 kB: set before iocInit reads it
        if int(os.environ.get("EPICS_CA_MAX_ARRAY_BYTES", "0")) < MAX_ARRAY_BYTES:
            os.environ["EPICS_CA_MAX_ARRAY_BYTES"] = str(MAX_ARRAY_BYTES)
        builder.SetDeviceName(f"{prefix}:TRAJ")
        self.axes = axes
        zeros = np.zeros(self.MAX_POINTS)
        self.positions = {
            axis: builder.WaveformOut(f"Positions{axis}", zeros, EGU="mm", PREC=3)
            for axis in axes
        }
        self.times = builder.WaveformOut(
            "Times", np.zeros(self.MAX_POINTS, dtype=np.int32), EGU="us"
        )
        self.indices = builder.WaveformOut(
            "PointIndices", np.arange(self.MAX_POINTS, dtype=np.int32)
        )
        self.num_points = builder.longOut(
            "NumPoints", initial_value=0, DRVL=0, DRVH=self.MAX_POINTS
        )
        statuses = ("Undefined", "Success", "Failure")
        self.build_status = builder.mbbIn("BuildStatus_RBV", *statuses, initial_value=0)
        self.build_message = builder.stringIn("BuildMessage_RBV", initial_value="")
        self.exec_status = builder.mbbIn(
            "ExecuteStatus_RBV", *statuses, initial_value=0
        )
        self.exec_state = builder.mbbIn(
            "ExecuteState_RBV", "Done", "Executing", initial_value=0
        )
        self.scanned = Throttled(builder.longIn("PointsScanned_RBV", initial_value=0))
        self.readbacks = {
            axis: builder.WaveformIn(f"Readbacks{axis}", zeros, EGU="mm", PREC=3)
            for axis in axes
        }
        builder.boolOut(
            "BuildProfile",
            ZNAM="Done",
            ONAM="Build",
            on_update=self._build,
            blocking=True,
            always_update=True,
        )
        builder.boolOut(
            "ExecuteProfile",
            ZNAM="Done",
            ONAM="Execute",
            on_update=self._execute,
            blocking=True,
            always_update=True,
        )
        builder.boolOut(
            "AbortProfile",
            ZNAM="Done",
            ONAM="Abort",
            on_update=self._abort,
            always_update=True,
        )
        self.built: tuple[dict[str, np.ndarray], np.ndarray, np.ndarray] | None = None
        self.aborted = False
        #: when the abort came (the loop's time), if it did
        self.abort_at = 0.0
        #: called with the ``PointIndices`` entry (the scan point's index) of
        #: each profile point reached whose entry is not -1 (the way a motion
        #: controller's position compare triggers a detector)
        self.point_listeners: list[Callable[[int], None]] = []

    def _build(self, value: int) -> None:
        if not value:
            return
        self.build_status.set(0)
        n = int(self.num_points.get())
        times = np.asarray(self.times.get())[:n]
        indices = np.asarray(self.indices.get())[:n]
        positions = {a: np.asarray(r.get())[:n] for a, r in self.positions.items()}
        problem = ""
        if n < 1:
            problem = "NumPoints must be at least 1"
        elif (
            len(times) < n
            or len(indices) < n
            or any(len(p) < n for p in positions.values())
        ):
            problem = "fewer array values than NumPoints"
        elif np.any(times <= 0):
            problem = "every time must be positive"
        if problem:
            self.built = None
            self.build_message.set(problem)
            self.build_status.set(2)
            return
        self.built = (positions, times, indices)
        self.build_message.set(f"built {n} points")
        self.build_status.set(1)

    def _abort(self, value: int) -> None:
        if value and not self.aborted:
            self.aborted = True
            self.abort_at = asyncio.get_running_loop().time()

    def stop_time(self) -> float:
        """Seconds an abort takes to stop the axes: their longest ``ACCL``."""
        return max((max(m.accl.get(), 0.0) for m in self.axes.values()), default=0.0)

    async def _execute(self, value: int) -> None:
        if not value:
            return
        if self.built is None:
            self.exec_status.set(2)
            return
        positions, times, indices = self.built
        self.aborted = False
        self.scanned.set(0)
        self.scanned.flush()  # reset before the execution shows
        self.exec_status.set(0)
        self.exec_state.set(1)
        # the motors' readbacks, posted at the status rate while it runs
        placed = {axis: Throttled(motor.rbv) for axis, motor in self.axes.items()}
        where = {axis: positions[axis].tolist() for axis in self.axes}
        due = np.cumsum(times, dtype=np.int64).tolist()  # us from the start
        points = indices.tolist()
        listeners = self.point_listeners
        schedule = Schedule()
        reached = 0
        try:
            for i, at in enumerate(due):
                deadline = schedule.start + at / 1e6
                await schedule.until(deadline)
                if self.aborted and deadline > self.abort_at + self.stop_time():
                    self.exec_status.set(2)
                    return
                for axis, record in placed.items():
                    record.set(where[axis][i])
                reached = i + 1
                self.scanned.set(reached)
                index = points[i]
                if index >= 0:
                    for listener in listeners:
                        listener(index)
            self.exec_status.set(1)
        finally:
            for record in placed.values():
                record.flush()
            self.scanned.flush()
            for axis, record in self.readbacks.items():
                # the motor was placed exactly at each point it reached
                record.set(np.asarray(positions[axis][:reached], dtype=float))
            self.exec_state.set(0)

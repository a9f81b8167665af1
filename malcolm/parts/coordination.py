"""The co-ordination layer: a beamline manager's parts over device managers.

A BeamlineManager (``malcolm/blocks/beamline/BeamlineManager.yaml``) is a
runnable block whose children are runnable device managers (a detector, a
motor controller, a Zebra): the design document's ``DetectorPart``,
``MotorPart`` and ``ZebraPart`` with ``input:`` the child's mri. Each is a
:class:`~malcolm.parts.demo.scan.RunnableChildPart` (so run, pause/seek,
resume, abort, reset and disable propagate as docs/controllers.md says)
that also:

- hands its child only the configure arguments the child takes: the scan
  (``generator``, ``axesToMove``, ``breakpoints``), ``fileDir`` and its raw
  file's ``formatName`` (``<scan's formatName>-<part name in lower case>``);
  every child is configured at once (the Configure phase runs them
  concurrently), so the detector and the Zebra are armed before anything
  moves;
- orders the children by their role in the triggering (``order``: the
  trigger source, the motion, is 1, the others 0): the motion is the last
  to start and the first to stop. Its run waits until every other child
  has started its run (or resumed: they re-armed in their Seek), so no
  trigger is missed; in a Seek (after a pause, or a put of
  ``completedSteps``) the others wait until the motion's pause has ended
  (its controller no longer produces triggers) before they stop and re-arm,
  so no trigger of the motion's deceleration is taken as a re-done point;
- validates in the same order: in each round of the beamline's Validate a
  child checks the scan once its siblings of a lower ``order`` have, with
  their changes (the motion checks its speeds at the duration the detector
  raised to its shortest frame, so the result does not depend on which
  child answers first);
- ends the scan in Fault when its child faults, with ``health`` saying
  ``<part>: <the child's health>``; when the beamline faults, the children
  still in the middle of the scan are aborted (the motion stops).

:class:`ScanFilePart` adds ``fileDir``, ``formatName`` and ``fileTemplate``
to configure and the ``datasets`` table, and writes the scan's one
NeXus-style file (:mod:`malcolm.io.nexus`) after each run, after an
abort with what was done, and on a Fault after a run began (from what the
raw files hold, once the children's aborts end), in a worker thread.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import logging
import re
import weakref
from pathlib import Path
from types import SimpleNamespace
from typing import Any

from malcolm.core import (
    BadValueError,
    MalcolmError,
    NumberMeta,
    StringMeta,
)
from malcolm.fsm import RunnableDevice
from malcolm.hooks import Task

from .base import Part, PartRegistrar, input_mri
from .datasets import datasets_meta
from .demo.scan import RunnableChildPart

__all__ = [
    "DetectorPart",
    "DeviceChildPart",
    "MotorPart",
    "ScanFilePart",
    "ZebraPart",
    "datasets_meta",
]

log = logging.getLogger(__name__)

#: the scan's own arguments, passed on to every child that takes them
SCAN_PARAMS = ("generator", "axesToMove", "breakpoints")
#: the beamline's file arguments
FILE_PARAMS = ("fileDir", "formatName", "fileTemplate")
#: beamline states in which a child's Fault ends the scan in Fault
_QUIET_STATES = {"Ready", "Fault", "Disabled", "Disabling", "Resetting"}


@functools.lru_cache(maxsize=256)
def safe_name(text: str) -> str:
    """``text`` as a file name: lower case, runs of other characters ``_``
    (kept for the few names a process has: a block's mri)."""
    return re.sub(r"[^a-z0-9_.-]+", "_", text.lower()).strip("_") or "scan"


class DeviceChildPart(RunnableChildPart):
    """A runnable device manager (``input``: its mri) in a beamline's scan.

    The child's raw file is ``<fileDir>/<formatName>-<name in lower
    case>.h5`` (its ``formatName`` argument); a child that takes no
    ``fileDir`` is given none.
    """

    #: whether the child moves motors (its run starts after the others')
    moves = False
    #: the child's place in the triggering: the highest (the trigger
    #: source) starts its run last and stops first in a Seek
    order = 0

    def __init__(
        self, name: str, input: str | None = None, mri: str | None = None
    ) -> None:
        super().__init__(name, input_mri(input, mri))
        self.started = asyncio.Event()
        self._watches: list[Any] = []
        self._child_state: Any = None
        self._abort_fut: asyncio.Future[Any] | None = None
        #: Seek phases this part has begun and ended (every part takes part
        #: in each, so the counts of the parts keep step)
        self._seeks_begun = 0
        self._seeks_ended = 0
        self._seek_ended = asyncio.Event()
        #: per device being validated, this part's validate of each round:
        #: the changes it returned (None if it failed), and the rounds begun
        self._validations: weakref.WeakKeyDictionary[
            Any, list[asyncio.Future[dict[str, Any] | None]]
        ] = weakref.WeakKeyDictionary()
        self._validates_begun: weakref.WeakKeyDictionary[Any, int] = (
            weakref.WeakKeyDictionary()
        )

    @property
    def input(self) -> str:
        return self.mri

    def setup(self, registrar: PartRegistrar) -> None:
        super().setup(registrar)
        self._block = registrar.controller.block

    # ---- what the child is given
    def _child_method(self, method: str) -> Any:
        """The child block's method ``method`` itself (LookupError if none):
        read in place, not copied out as data (``Process.get`` of a method
        serializes it, its last call's arguments included)."""
        controller = self._controller
        assert controller is not None and controller.process is not None
        return controller.process.get_block(self.mri)[method]

    def child_takes(self) -> set[str]:
        """The arguments the child's configure() takes (none if unknown)."""
        try:
            takes = self._child_method("configure").meta.takes
        except (LookupError, AttributeError):
            return set()
        return set(getattr(takes, "elements", None) or ())

    def allowed(self, task: Task, method: str) -> bool:
        """Whether the child's ``method`` may be called now (read in place)."""
        try:
            return bool(self._child_method(method).meta.writeable)
        except (LookupError, AttributeError):
            return False

    def raw_name(self, device: Any) -> str:
        """The child's ``formatName``: the scan's, then the part's name."""
        scan = device.params.get("formatName") or safe_name(device.mri)
        return f"{scan}-{self.name.lower()}"

    def _child_params(self, device: Any) -> dict[str, Any]:
        takes = self.child_takes()
        params = {k: device.params[k] for k in SCAN_PARAMS if k in device.params}
        if "fileDir" in takes:
            params["fileDir"] = device.params.get("fileDir", "")
        if "formatName" in takes:
            params["formatName"] = self.raw_name(device)
        return {k: v for k, v in params.items() if k in takes or k == "generator"}

    @RunnableDevice.Validate
    async def validate(self, task: Task, device: Any) -> dict[str, Any]:
        """The child checks the scan once every sibling of a lower ``order``
        has checked it in this round, with their changes: the motion checks
        its speeds at the duration the detector raised, not at the one
        asked for (a refusal of a duration nobody keeps). Returns the
        changes to the scan's arguments (the siblings return their own)."""
        index = self._validates_begun.get(device, 0)
        self._validates_begun[device] = index + 1
        mine = self.validation(device, index)
        try:
            earlier: dict[str, Any] = {}
            inactive = getattr(self._controller, "inactive", ())
            for part in sorted(self.siblings(), key=lambda p: p.order):
                if part.order < self.order and part.name not in inactive:
                    tweaks = await part.validation(device, index)
                    if tweaks is None:
                        mine.set_result(None)
                        return {}  # a sibling refused: the phase fails anyway
                    earlier.update(tweaks)
            checked = device
            if earlier:
                params = {**device.params, **earlier}
                checked = SimpleNamespace(params=params, mri=device.mri)
            tweaks = await super().validate(task, checked)
            tweaks = {k: v for k, v in tweaks.items() if k in SCAN_PARAMS}
            if earlier:  # the scan as this child left it, the siblings' changes in
                tweaks = {**earlier, **tweaks}
        except BaseException:
            if not mine.done():
                mine.set_result(None)
            raise
        mine.set_result(tweaks)
        return tweaks

    def validation(self, device: Any, index: int) -> asyncio.Future[Any]:
        """This part's ``index``-th validate of ``device``: its result is
        the changes it returned, None if it failed (made here if the part
        has not begun it yet)."""
        rounds = self._validations.setdefault(device, [])
        while len(rounds) <= index:
            rounds.append(asyncio.get_running_loop().create_future())
        return rounds[index]

    @RunnableDevice.Configure
    async def configure(self, task: Task, device: Any) -> None:
        self._seeks_begun = self._seeks_ended = 0
        self._watch(task)
        try:
            await super().configure(task, device)
        except MalcolmError as e:
            raise MalcolmError(f"{self.name}: {e}") from None

    # ---- seek: the trigger source first
    @RunnableDevice.Seek
    async def seek(self, task: Task, device: Any) -> None:
        """Pause the child at the beamline's step, once every sibling of a
        higher ``order`` (the motion) has paused: a trigger still coming
        from it would otherwise be taken as the first re-done point by a
        detector already re-armed."""
        self._seeks_begun += 1
        mine = self._seeks_begun
        try:
            for part in self.siblings():
                if part.order > self.order:
                    await part.seek_ended(mine)
            await super().seek(task, device)
        finally:
            self._seeks_ended = mine
            self._seek_ended.set()

    async def seek_ended(self, count: int) -> None:
        """Wait until this part's ``count``-th Seek has ended."""
        while self._seeks_ended < count:
            self._seek_ended.clear()
            await self._seek_ended.wait()

    # ---- run: the motion last
    @RunnableDevice.PreRun
    async def pre_run(self) -> None:
        self.started = asyncio.Event()

    def siblings(self) -> list[DeviceChildPart]:
        assert self._controller is not None
        return [
            p
            for p in self._controller.parts.values()
            if isinstance(p, DeviceChildPart) and p is not self
        ]

    def _note_started(self, _: Any = None) -> None:
        if not (self.allowed_now("run") or self.allowed_now("resume")):
            self.started.set()

    def allowed_now(self, method: str) -> bool:
        """Whether the child's ``method`` may be called now (its meta's
        ``writeable``, read in place as :meth:`allowed` reads it)."""
        try:
            return bool(self._child_method(method).meta.writeable)
        except (LookupError, AttributeError):
            return False

    @RunnableDevice.Run
    async def run(self, task: Task, device: Any) -> None:
        if self.moves:
            waits = [p.started.wait() for p in self.siblings() if p.order < self.order]
            if waits:
                await asyncio.gather(*waits)
        process = task.process
        subs = [
            process.subscribe(
                [self.mri, method, "meta", "writeable"], self._note_started, False
            )
            for method in ("run", "resume")
        ]
        try:
            await super().run(task, device)
        except asyncio.CancelledError:
            raise
        except MalcolmError as e:
            raise MalcolmError(f"{self.name}: {self.child_health(e)}") from None
        finally:
            self.started.set()
            for sub in subs:
                process.unsubscribe(sub)

    def child_health(self, error: BaseException) -> str:
        """What went wrong with the child: its health if it says, else
        the error."""
        controller = self._controller
        assert controller is not None and controller.process is not None
        with contextlib.suppress(LookupError):
            health = controller.process.get([self.mri, "health", "value"])
            if health and health != "OK":
                return str(health)
        return str(error)

    @RunnableDevice.Reset
    async def reset(self, task: Task, device: Any) -> None:
        self._seeks_begun = self._seeks_ended = 0
        await super().reset(task, device)

    @RunnableDevice.Abort
    async def abort(self, task: Task, device: Any) -> None:
        self._seeks_begun = self._seeks_ended = 0
        self._abort_fut = asyncio.ensure_future(super().abort(task, device))
        await self._abort_fut

    async def aborted(self) -> None:
        """Wait for the abort of the child that this part's Abort started."""
        fut = self._abort_fut
        if fut is not None:
            with contextlib.suppress(Exception):
                await asyncio.shield(fut)

    # ---- faults: the child's ends the scan; the beamline's stops the child
    def _watch(self, task: Task) -> None:
        if self._watches:
            return
        process = task.process
        assert self._controller is not None
        own = self._controller.mri
        self._watches = [
            process.subscribe(
                [self.mri, "state", "value"], self._on_child_state, delta=False
            ),
            process.subscribe([own, "state", "value"], self._on_own_state, delta=False),
        ]

    def _on_child_state(self, state: Any) -> None:
        # only a move into Fault counts: a child found in Fault when the
        # watch starts is reset by Configure, as RunnableChildPart does
        before, self._child_state = self._child_state, state
        controller = self._controller
        if state != "Fault" or before in (None, "Fault") or controller is None:
            return
        if controller.block.state.value in _QUIET_STATES:
            return
        reason = f"{self.name}: {self.child_health(MalcolmError('Fault'))}"
        controller.fault_now(reason)

    def _on_own_state(self, state: Any) -> None:
        if state != "Fault" or self._controller is None:
            return
        process = self._controller.process
        if process is None or not self.allowed_now("abort"):
            return
        if self.allowed_now("configure") or self.allowed_now("reset"):
            return

        async def stop_child() -> None:
            with contextlib.suppress(Exception):
                await process.post([self.mri, "abort"])

        fut = self._abort_fut = asyncio.ensure_future(stop_child())
        fut.add_done_callback(lambda f: f.cancelled() or f.exception())


class DetectorPart(DeviceChildPart):
    """A detector manager in the scan: armed at configure, waits for frames.

    Adds ``frameTimeout`` to the beamline's configure (0: the detector's
    default), handed to a detector whose configure takes it: its run faults
    when no frame comes for that long, saying what it knows of why
    (``detector_manager.stall_message``).
    """

    def setup(self, registrar: PartRegistrar) -> None:
        super().setup(registrar)
        registrar.add_configure_arg(
            "frameTimeout",
            NumberMeta(
                "float64",
                "Seconds without a new frame before the detector faults (0:"
                " the detector's default, 3 x the longest point + 10 s)",
            ),
            0.0,
        )

    def _child_params(self, device: Any) -> dict[str, Any]:
        params = super()._child_params(device)
        timeout = device.params.get("frameTimeout")
        if timeout and "frameTimeout" in self.child_takes():
            params["frameTimeout"] = timeout
        return params


class ZebraPart(DeviceChildPart):
    """A Zebra manager in the scan: armed before the motion starts."""


class MotorPart(DeviceChildPart):
    """A motor controller manager: its run (the motion) starts once the
    others have started theirs; its ``simultaneousAxes`` become the
    beamline's."""

    moves = True
    order = 1

    @RunnableDevice.Init
    async def init(self, task: Task) -> None:
        self._follow_axes(task)

    @RunnableDevice.Reset
    async def reset(self, task: Task, device: Any) -> None:
        await super().reset(task, device)
        self._follow_axes(task)

    def _follow_axes(self, task: Task) -> None:
        if getattr(self, "_axes_sub", None) is not None:
            return
        try:
            self._axes_sub = task.process.subscribe(
                [self.mri, "simultaneousAxes", "value"], self._set_axes, delta=False
            )
        except LookupError:
            self._axes_sub = None

    def _set_axes(self, axes: Any) -> None:
        if axes is not None and "simultaneousAxes" in self._block:
            self._block.simultaneousAxes.set_value(list(axes))


class ScanFilePart(Part):
    """The scan's one file: ``<fileDir>/<fileTemplate % formatName>``.

    configure() takes ``fileDir`` ("" = no file; default ``file_dir``),
    ``formatName`` (default:
    the block's mri in lower case) and ``fileTemplate`` (default
    ``%s.nxs``). After PostConfigure ``datasets`` lists what the file will
    hold; after each run (PostRunArmed, PostRunReady), after an abort and
    when the block faults after a run began the file is (re)written from the
    children's raw files, in a worker thread.
    """

    #: seconds a fault's file waits for the children's aborts to end
    FAULT_ABORT_WAIT = 30.0

    def __init__(self, name: str = "file", file_dir: str = "") -> None:
        super().__init__(name)
        self.file_dir = file_dir
        self.path: Path | None = None
        self.last_result: Any = None
        self._device: Any = None  # the scan configured
        self._ran = False  # whether a run of it has begun
        self._state_sub: Any = None
        self._fault_write: asyncio.Future[Any] | None = None

    def setup(self, registrar: PartRegistrar) -> None:
        self._controller = registrar.controller
        registrar.add_configure_arg(
            "fileDir",
            StringMeta("Directory of the scan's files; '' = none"),
            self.file_dir,
        )
        registrar.add_configure_arg(
            "formatName", StringMeta("Name of the scan's file (default: the mri)"), ""
        )
        registrar.add_configure_arg(
            "fileTemplate", StringMeta("The file's name, % formatName"), "%s.nxs"
        )
        self.datasets = registrar.add_attribute(
            "datasets", datasets_meta("Datasets of the scan's file"), _table([])
        )

    def devices(self) -> list[DeviceChildPart]:
        return [
            p for p in self._controller.parts.values() if isinstance(p, DeviceChildPart)
        ]

    @RunnableDevice.Validate
    async def validate(self, task: Task, device: Any) -> dict[str, Any]:
        template = device.params.get("fileTemplate", "%s.nxs")
        try:
            name = template % "x"
        except (TypeError, ValueError) as e:
            raise BadValueError(
                f"{device.mri}.configure.fileTemplate: {template!r} must hold"
                f" one %s ({e})"
            ) from None
        if "/" in name:
            raise BadValueError(
                f"{device.mri}.configure.fileTemplate: {template!r} must name a"
                " file, not a path"
            )
        return {}

    @RunnableDevice.Configure
    async def configure(self, task: Task, device: Any) -> None:
        self._device, self._ran = device, False
        if self._state_sub is None:
            self._state_sub = task.process.subscribe(
                [self._controller.mri, "state", "value"], self._on_state, delta=False
            )
        file_dir = device.params.get("fileDir", "")
        if not file_dir:
            self.path = None
            return
        name = device.params.get("formatName") or safe_name(device.mri)
        self.path = Path(file_dir) / (device.params.get("fileTemplate") % name)

    @RunnableDevice.PostConfigure
    async def post_configure(self, task: Task, device: Any) -> None:
        if self.path is None:
            self.datasets.set_value(_table([]))
            return
        rows = self.child_rows(task, device)
        names = {r.name for r in rows}
        points = device.points
        axes = list(points.axes) if points is not None else []
        from malcolm.io.nexus import DatasetRow

        out = [
            DatasetRow(
                r.name,
                self.path.name,
                r.type,
                r.rank,
                f"/entry/{r.group}/{r.leaf}",
                "/entry/uniqueid",
            )
            for r in rows
        ]
        for axis in axes:
            if f"{axis}.value_set" not in names:
                out.append(
                    DatasetRow(
                        f"{axis}.value_set",
                        self.path.name,
                        "position_set",
                        0,
                        f"/entry/{axis}/value_set",
                        "/entry/uniqueid",
                    )
                )
        self.datasets.set_value(_table(out))

    def child_rows(self, task: Task | None, device: Any) -> list[Any]:
        """The ``datasets`` rows of every device child that has them; a
        name the child gave under its raw file's name (``scan-det.data``)
        is put under the part's name in lower case (``det.data``)."""
        from dataclasses import replace

        from malcolm.io.nexus import rows_from_table

        rows = []
        for part in self.devices():
            process = task.process if task is not None else self._controller.process
            try:
                table = process.get([part.mri, "datasets", "value"])
            except LookupError:
                continue
            if not table:
                continue
            raw = f"{part.raw_name(device)}."
            for row in rows_from_table(_columns(table)):
                if row.name.startswith(raw):
                    group = part.name.lower()
                    row = replace(row, name=group + "." + row.name[len(raw) :])
                rows.append(row)
        return rows

    @RunnableDevice.PreRun
    async def pre_run(self, task: Task, device: Any) -> None:
        self._ran = True

    @RunnableDevice.PostRunArmed
    async def post_run_armed(self, task: Task, device: Any) -> None:
        await self.write(task, device)

    @RunnableDevice.PostRunReady
    async def post_run_ready(self, task: Task, device: Any) -> None:
        await self.write(task, device)

    @RunnableDevice.Abort
    async def abort(self, task: Task, device: Any) -> None:
        await asyncio.sleep(0)  # the children's parts start their aborts
        await asyncio.gather(*(p.aborted() for p in self.devices()))
        if device.points is not None and device.completedSteps > 0:
            await self.write(task, device)

    # ---- a fault: the points taken are still written
    def _on_state(self, state: Any) -> None:
        if state != "Fault" or not self._ran or self.path is None:
            return
        if self._fault_write is not None and not self._fault_write.done():
            return
        self._fault_write = fut = asyncio.ensure_future(self._write_on_fault())
        fut.add_done_callback(lambda f: f.cancelled() or f.exception())

    async def _write_on_fault(self) -> None:
        """Once the children's aborts (started by the device parts when the
        beamline faulted) have ended, or after :attr:`FAULT_ABORT_WAIT`,
        write the file from what the raw files hold; what cannot be read
        is logged and named in the file's ``problems`` attribute."""
        device = self._device
        self._ran = False
        await asyncio.sleep(0)  # the device parts start their children's aborts
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(
                asyncio.gather(*(p.aborted() for p in self.devices())),
                self.FAULT_ABORT_WAIT,
            )
        health = self._controller.block.health.value
        try:
            await self.write(None, device, {"fault": str(health)})
        except Exception as e:  # nothing left to fault: say so, never raise
            log.error(
                "%s: the file of the faulted scan %s: %s", device.mri, self.path, e
            )

    async def write(
        self, task: Task | None, device: Any, extra: dict[str, Any] | None = None
    ) -> None:
        """Assemble the file in a worker thread; problems are logged (the
        rest is written), put in the file's ``problems`` attribute and kept
        in ``last_result``. ``extra`` attributes go on ``/entry``."""
        if self.path is None or device.points is None:
            return
        from malcolm.io.nexus import assemble

        rows = self.child_rows(task, device)
        points = device.points.copy()
        path = self.path
        attrs = {"scan_mri": device.mri, "completed_steps": device.completedSteps}
        attrs.update(extra or {})

        def work() -> Any:
            import numpy as np  # loaded with the first file, not at start-up

            demands = {
                axis: np.concatenate(list(points.column("positions", axis)))
                for axis in points.axes
            }
            return assemble(path, path.parent, rows, points.shape, demands, attrs)

        self.last_result = result = await asyncio.to_thread(work)
        for problem in result.problems:
            log.warning("%s: %s: %s", device.mri, path, problem)


def _columns(table: Any) -> dict[str, Any]:
    """A table value (a Table or a dict of columns) as a dict of columns."""
    if isinstance(table, dict):
        return {k: v for k, v in table.items() if k != "typeid"}
    to_dict = getattr(table, "to_dict", None)
    if to_dict is not None:
        return {k: v for k, v in to_dict().items() if k != "typeid"}
    return {k: table[k] for k in table}


def _table(rows: list[Any]) -> dict[str, list[Any]]:
    return {
        "name": [r.name for r in rows],
        "filename": [r.filename for r in rows],
        "type": [r.type for r in rows],
        "rank": [r.rank for r in rows],
        "path": [r.path for r in rows],
        "uniqueid": [r.uniqueid for r in rows],
    }

"""Channel Access done by the raw library: the floor of issue 13's configures.

What a configure of the simulated detector and motion controller must send
and wait for, whatever framework does it: the same PVs and values as the
managers' configures (:mod:`malcolm.parts.detector_manager`,
:mod:`malcolm.parts.motion_manager`), in the same chains and at the same
concurrency, the puts with completion, the waits on the readbacks the
managers need (a plugin running, a writer capturing, a driver acquiring:
pyepics monitors; a build's status: a pyepics get), and the raw file the
motion manager makes (h5py, in a thread beside the puts, as the manager
does). The detector's file is the IOC's (its ``Capture``).

:class:`RawCA` uses pyepics' binding of libca as a bare client would: a
put is ``ca_array_put_callback`` of a ctypes array (numpy copies the
numbers in: pyepics' own ``ca.put`` turns an array into a Python list
first, milliseconds for a 20,001-point trajectory or 65 kB of XML), its
completion a ``threading.Event`` set in libca's thread; a chain that waits
is a thread blocked on those events. Nothing of malcolm's runs in a chain
(its XML text and trajectory profile are computed before, untimed).
"""

from __future__ import annotations

import concurrent.futures
import ctypes
import threading
import time
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np

#: seconds a raw chain waits for a put's completion or a readback
WAIT = 10.0


class RawCA:
    """Connected PVs by name: puts with completion, gets and monitors."""

    def __init__(self, names: Iterable[str], monitored: Iterable[str] = ()) -> None:
        from epics import ca

        self._ca = ca
        ca.use_initial_context()
        monitored = list(monitored)
        self.chids = {
            n: ca.create_channel(n, connect=False, auto_cb=False)
            for n in [*names, *monitored]
        }
        for name, chid in self.chids.items():
            if not ca.connect_channel(chid, timeout=5.0):
                raise RuntimeError(f"{name}: not connected")
        self._types = {
            n: (ca.field_type(c), ca.element_count(c)) for n, c in self.chids.items()
        }
        self._failed: list[str] = []
        self._changed = threading.Condition()
        self.latest: dict[str, Any] = {}
        self._subscriptions = [
            ca.create_subscription(
                self.chids[n], use_time=False, callback=self._on_event
            )
            for n in monitored
        ]
        for name in monitored:
            self.until(name, lambda v: v is not None)
        self.pool = concurrent.futures.ThreadPoolExecutor(4)

    def close(self) -> None:
        self.pool.shutdown()
        for _, _, evid in self._subscriptions:
            self._ca.clear_subscription(evid)

    # ---- libca's threads
    def _on_event(self, pvname: str = "", value: Any = None, **_: Any) -> None:
        with self._changed:
            self.latest[pvname] = value
            self._changed.notify_all()

    # ---- what a chain does (its own thread)
    def put(self, name: str, value: Any) -> threading.Event:
        """Put with completion; the event is set once the IOC completed it."""
        ca = self._ca
        ca.use_initial_context()
        ftype, count = self._types[name]
        data, n = _marshal(value, ftype, count)
        done = threading.Event()
        token = (done, self._failed)
        holder = ctypes.py_object(token)
        with _pending_lock:
            _pending[id(token)] = (holder, data)
        status = ca.libca.ca_array_put_callback(
            ftype, n, self.chids[name], data, _put_callback(), holder
        )
        if status != 1:  # ECA_NORMAL
            with _pending_lock:
                _pending.pop(id(token), None)
            raise RuntimeError(f"{name}: put of {value!r} refused ({status})")
        ca.libca.ca_flush_io()
        return done

    def wait(self, events: Iterable[threading.Event]) -> None:
        """Wait until every put of ``events`` completed."""
        for done in events:
            if not done.wait(WAIT):
                raise TimeoutError("a put did not complete")
        if self._failed:
            raise RuntimeError(f"a put failed: {self._failed}")

    def put_all(self, puts: Mapping[str, Any]) -> None:
        """Put each at once, wait for them all."""
        self.wait([self.put(name, value) for name, value in puts.items()])

    def get(self, name: str) -> Any:
        """The PV's value now (a pyepics get)."""
        self._ca.use_initial_context()
        return self._ca.get(self.chids[name], timeout=WAIT)

    def until(self, name: str, want: Any) -> None:
        """Wait until the monitor of ``name`` brings ``want`` (or a value
        ``want(value)`` is true of)."""
        match = want if callable(want) else (lambda v: v == want)
        deadline = time.monotonic() + WAIT
        with self._changed:
            while not match(self.latest.get(name)):
                left = deadline - time.monotonic()
                if left <= 0 or not self._changed.wait(left):
                    raise TimeoutError(f"{name} is {self.latest.get(name)!r}")


#: puts in flight, by id of their token: (its py_object, the data), kept
#: until libca calls back, whatever became of the RawCA that sent them (a
#: busy put, the writer's Capture, may complete after its RawCA is closed)
_pending: dict[int, tuple[Any, Any]] = {}
_pending_lock = threading.Lock()
#: the ctypes put callback libca calls: made once, never freed
_cb_put: Any = None


def _put_callback() -> Any:
    global _cb_put
    if _cb_put is None:
        from epics import dbr

        _cb_put = dbr.make_callback(_on_put, dbr.event_handler_args)
    return _cb_put


def _on_put(args: Any) -> None:
    """A put's completion (libca's thread): note a failure, set its event."""
    from epics import dbr

    token = args.usr
    with _pending_lock:
        kept = _pending.pop(id(token), None)
    done, failed = token
    if args.status != dbr.ECA_NORMAL:
        failed.append(str(args.status))
    done.set()
    del kept


def _marshal(value: Any, ftype: int, count: int) -> tuple[Any, int]:
    """``value`` as a ctypes array of the PV's native type (numpy copies the
    numbers in), and its length."""
    from epics import dbr

    ctype = dbr.Map[ftype]
    if isinstance(value, str):
        if ftype == dbr.STRING:
            data = (1 * ctype)()
            data[0].value = value.encode()[:39]
            return data, 1
        value = np.frombuffer(value.encode() + b"\0", dtype=np.uint8)
    values = np.atleast_1d(np.asarray(value))
    n = min(len(values), count)
    native = np.ascontiguousarray(values[:n].astype(np.dtype(ctype)))
    data = (n * ctype)()
    ctypes.memmove(data, native.ctypes.data, native.nbytes)
    return data, n


# ---- the detector's configure (ADCore.DetectorManager's DetectorManagerPart)

#: states of ``CAM:DetectorState_RBV`` and ``Running_RBV``/``Capture_RBV``
ACQUIRE, RUNNING, CAPTURING = 1, 1, 1


def detector_pvs(prefix: str) -> tuple[list[str], list[str]]:
    """The PVs a raw detector configure puts to and the ones it monitors."""
    puts = [
        f"{prefix}:CAM:{n}"
        for n in ("Exposure", "AcquirePeriod", "ImageMode", "TriggerMode",
                  "ArrayCallbacks", "NumImages", "Acquire", "Stop")
    ] + [
        f"{prefix}:POS:{n}"
        for n in ("IDStart", "EnableCallbacks", "Delete", "Filename", "Running",
                  "Stop")
    ] + [
        f"{prefix}:HDF:{n}"
        for n in ("EnableCallbacks", "FilePath", "FileName", "FileTemplate",
                  "NumCapture", "Append", "LazyOpen", "Capture", "Stop")
    ]  # fmt: skip
    monitored = [
        f"{prefix}:CAM:DetectorState_RBV",
        f"{prefix}:POS:Running_RBV",
        f"{prefix}:HDF:Capture_RBV",
    ]
    return puts, monitored


def detector_settings(
    prefix: str, exposure: float, frames: int, file_dir: str, name: str, external: bool
) -> tuple[dict[str, Any], dict[str, Any]]:
    """Everything a first configure sets (the plugin chain's, the writer
    chain's), as the manager sets it for a fresh file at point 0; the
    manager puts, and a raw client need put, only what the IOC does not
    hold already."""
    other = {
        f"{prefix}:CAM:Exposure": exposure,
        f"{prefix}:CAM:AcquirePeriod": exposure,
        f"{prefix}:CAM:ImageMode": 1,  # Multiple
        f"{prefix}:CAM:TriggerMode": int(external),
        f"{prefix}:CAM:ArrayCallbacks": 1,
        f"{prefix}:CAM:NumImages": frames,
        f"{prefix}:POS:IDStart": 1,
        f"{prefix}:POS:EnableCallbacks": 1,
    }
    writer = {
        f"{prefix}:HDF:EnableCallbacks": 1,
        f"{prefix}:HDF:FilePath": file_dir.rstrip("/") + "/",
        f"{prefix}:HDF:FileName": name,
        f"{prefix}:HDF:FileTemplate": "%s%s.h5",
        f"{prefix}:HDF:NumCapture": frames,
        f"{prefix}:HDF:Append": 0,
        f"{prefix}:HDF:LazyOpen": 0,
    }
    return other, writer


def detector_configure(
    raw: RawCA,
    prefix: str,
    other: Mapping[str, Any],
    writer: Mapping[str, Any],
    batches: list[str],
    external: bool,
) -> None:
    """The detector manager's configure on the wire: two chains at once
    (the writer's settings, then its capture, until ``Capture_RBV``; the
    plugin cleared and its XML ``batches`` sent at once while the other
    settings go, then started, until ``Running_RBV``), then (External) the
    driver acquiring, until ``DetectorState_RBV`` is Acquire. The busy puts
    (Capture, Running, Acquire) complete at the run's end or a stop."""

    def writer_chain() -> None:
        raw.put_all(writer)
        raw.put(f"{prefix}:HDF:Capture", 1)
        raw.until(f"{prefix}:HDF:Capture_RBV", CAPTURING)

    writing = raw.pool.submit(writer_chain)
    settings = [raw.put(pv, value) for pv, value in other.items()]
    raw.wait([raw.put(f"{prefix}:POS:Delete", 1)])
    raw.wait([raw.put(f"{prefix}:POS:Filename", xml) for xml in batches])
    raw.wait(settings)
    raw.put(f"{prefix}:POS:Running", 1)
    raw.until(f"{prefix}:POS:Running_RBV", RUNNING)
    writing.result()
    if external:
        raw.put(f"{prefix}:CAM:Acquire", 1)
        raw.until(f"{prefix}:CAM:DetectorState_RBV", ACQUIRE)


def detector_stop(raw: RawCA, prefix: str) -> None:
    """The manager's reset on the wire (not timed): the driver, then the
    plugins, stopped."""
    raw.put_all({f"{prefix}:CAM:Stop": 1})
    raw.until(f"{prefix}:CAM:DetectorState_RBV", 0)
    raw.put_all({f"{prefix}:POS:Stop": 1, f"{prefix}:HDF:Stop": 1})
    raw.until(f"{prefix}:POS:Running_RBV", 0)
    raw.until(f"{prefix}:HDF:Capture_RBV", 0)


# ---- the motion controller's configure (pmac.MotorControllerManager)


def motion_pvs(prefix: str) -> tuple[list[str], list[str]]:
    traj = [
        f"{prefix}:TRAJ:{n}"
        for n in ("PositionsA", "PositionsB", "Times", "PointIndices", "NumPoints",
                  "BuildProfile", "BuildStatus_RBV")
    ]  # fmt: skip
    return traj, []


def motion_arrays(prefix: str, profile: Any) -> dict[str, Any]:
    """What the manager writes of ``profile`` (two axes, x and y on A and B)."""
    return {
        f"{prefix}:TRAJ:PositionsA": profile.positions["x"],
        f"{prefix}:TRAJ:PositionsB": profile.positions["y"],
        f"{prefix}:TRAJ:Times": profile.times,
        f"{prefix}:TRAJ:PointIndices": profile.indices,
        f"{prefix}:TRAJ:NumPoints": profile.size,
    }


def motion_configure(
    raw: RawCA, prefix: str, arrays: Mapping[str, Any], make_file: Any = None
) -> None:
    """The motion manager's configure on the wire: the arrays the controller
    does not hold sent at once, then BuildProfile with completion and its
    status read (Success or the build failed); ``make_file`` (the raw
    file, h5py) in a thread meanwhile. (No run-up move: the managers'
    repeated scans start within the motors' deadband.)"""
    making = raw.pool.submit(make_file) if make_file is not None else None
    raw.put_all(arrays)
    raw.put_all({f"{prefix}:TRAJ:BuildProfile": 1})
    status = raw.get(f"{prefix}:TRAJ:BuildStatus_RBV")
    if status != 1:  # Success
        raise RuntimeError(f"{prefix}:TRAJ: build status {status}")
    if making is not None:
        making.result()

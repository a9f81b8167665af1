"""Build and run the simulated beamline IOC (one per process: softioc)."""

from __future__ import annotations

import os
import sys

from .detector import make_detector
from .motion import Motor, Trajectory
from .runner import READY

#: EPICS callback ring size (softioc leaves EPICS' default, 2000)
CALLBACK_QUEUE = 100000


def build(prefix: str, bench_blocks: int = 0) -> dict[str, object]:
    """Make every record of the IOC under ``prefix`` (and, with
    ``bench_blocks``, the benchmark's: :mod:`.bench`)."""
    from softioc import builder

    m1 = Motor(f"{prefix}:M1")
    m2 = Motor(f"{prefix}:M2")
    detector = make_detector(prefix)
    trajectory = Trajectory(prefix, {"A": m1, "B": m2})
    # External triggers: one frame per trajectory point, as a position
    # compare (a Zebra) triggers the detector on real hardware
    trajectory.point_listeners.append(detector.trigger)
    things = {
        "detector": detector,
        "m1": m1,
        "m2": m2,
        "trajectory": trajectory,
    }
    if bench_blocks:
        from .bench import Bench

        things["bench"] = Bench(prefix, bench_blocks)
    builder.LoadDatabase()
    return things


def run(prefix: str, bench_blocks: int = 0) -> None:
    """Serve the IOC until stdin closes or the process is signalled."""
    from softioc import softioc
    from softioc.imports import callbackSetQueueSize

    # every record .set() is a callback; frames every 0.5 ms update several
    # records each, more than the default ring of 2000 holds in a burst (a
    # lost callback can leave a put never completed)
    callbackSetQueueSize(CALLBACK_QUEUE)
    from .dispatch import Dispatcher

    dispatcher = Dispatcher()
    things = build(prefix, bench_blocks)
    softioc.iocInit(dispatcher, enable_pva=False)
    print(f"{READY}: prefix {prefix}, {len(things)} devices", flush=True)
    try:
        sys.stdin.read()  # until stdin closes (the parent went away)
    except KeyboardInterrupt:
        pass
    os._exit(0)  # softioc's threads do not end by themselves

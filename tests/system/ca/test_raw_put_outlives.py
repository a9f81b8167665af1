"""``benchmarks.raw_ca.RawCA``: a put still in flight when its RawCA is
closed and collected completes later without harm.

libca calls a put's completion through the ctypes callback and the
``py_object`` the put gave it. RawCA kept both on the instance, so a busy
put that outlived it (the writer's ``Capture``, completed once a stop
reached the IOC) called freed memory: the shuffled CA directory crashed
the test process (SIGSEGV, exit 139) after test_raw_floor's detector test.
The scenario runs in a subprocess, so a crash fails this test only."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from .conftest import PREFIX

ROOT = Path(__file__).resolve().parents[3]

SCENARIO = f"""
import gc, time
import epics
from benchmarks import raw_ca

cam = "{PREFIX}:CAM:"
settings = {{cam + "ImageMode": 1, cam + "NumImages": 100000,
            cam + "TriggerMode": 0, cam + "AcquirePeriod": 0.01}}
before = {{pv: epics.caget(pv, timeout=10) for pv in settings}}
raw = raw_ca.RawCA([*settings, cam + "Acquire"])
raw.put_all(settings)
busy = raw.put(cam + "Acquire", 1)  # completes when the acquisition ends
time.sleep(0.2)
assert not busy.is_set()
raw.close()
del raw
gc.collect()
for _ in range(3):  # whatever the freed memory is used for meanwhile
    [bytearray(64) for _ in range(100000)]
    gc.collect()
assert epics.caput(cam + "Stop", 1, wait=True, timeout=10) == 1
deadline = time.monotonic() + 10
while not busy.is_set():  # the completion came, in libca's thread
    assert time.monotonic() < deadline, "the Acquire put did not complete"
    time.sleep(0.01)
for pv, value in before.items():  # the session IOC as it was
    epics.caput(pv, value, wait=True, timeout=10)
print("survived")
"""


def test_a_busy_put_completes_after_its_raw_client_is_gone(ioc):
    done = subprocess.run(
        [sys.executable, "-c", SCENARIO],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert done.returncode == 0 and "survived" in done.stdout, (
        done.returncode,
        done.stdout,
        done.stderr[-2000:],
    )

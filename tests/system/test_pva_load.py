"""Load: 50 clients monitoring every block of the served demo while a scan
runs; every client ends with the final values, and the server's memory is
flat over repeated runs. Also: a client that searches while the server is
starting finds its blocks.

The clients subscribe through :func:`monitor`, not p4p's
``Context.monitor``, whose start-up race lost a subscription's first value
for ever now and then under load (see tests/system/p4p_monitor.py): that,
not the server, was this test's "not seen in time"."""

from __future__ import annotations

import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import pytest
from p4p import Type, Value

from malcolm.demo import demo_generator
from malcolm.io.pva.convert import to_value
from malcolm.io.pva.server import RELEASE_DELAY

from .conftest import Served, launch, wait_ready
from .p4p_monitor import monitor

CLIENTS = 50
RUNS = 3
STEPS = 30
MRIS = ["HELLO", "COUNTER", "MOTOR:X", "MOTOR:Y", "DET1", "DET2", "SCAN"]


def rss_kib(pid: int) -> int:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    raise AssertionError("no VmRSS")


def call(ctx: Any, method: str, args: dict[str, Any] | None = None) -> Any:
    value = to_value(args) if args else Value(Type([]), {})
    return ctx.rpc(f"SCAN.{method}", value, timeout=60)


class Watcher:
    """One client: a monitor of every block, keeping the last of each."""

    def __init__(self, served: Served) -> None:
        self.ctx = served.context()
        self.last: dict[str, Any] = {}
        self.lock = threading.Lock()
        self.events: list[tuple[str, str]] = []
        self.subs = [
            monitor(self.ctx, mri, self._keep(mri), notify_disconnect=True)
            for mri in MRIS
        ]

    def _keep(self, mri: str):
        def keep(value: Any) -> None:
            with self.lock:
                if isinstance(value, Exception):
                    self.events.append((mri, repr(value)))
                else:
                    self.last[mri] = value

        return keep

    def value(self, mri: str, path: str) -> Any:
        with self.lock:
            return self.last[mri][path] if mri in self.last else None

    def close(self) -> None:
        for sub in self.subs:
            sub.close()
        self.ctx.close()


def wait_until(check, timeout: float = 30, what: Any = None) -> None:
    deadline = time.monotonic() + timeout
    while not check():
        assert time.monotonic() < deadline, f"not seen in time: {what and what()}"
        time.sleep(0.05)


def final_seen(watcher: Watcher, run: int) -> bool:
    return (
        watcher.value("SCAN", "completedSteps.value") == STEPS
        and watcher.value("SCAN", "state.value") == "Finished"
        and watcher.value("COUNTER", "counter.value") == run
    )


def lagging(watchers: list[Watcher], run: int) -> list[Any]:
    """What the clients that have not seen the final values hold instead."""
    return [
        (
            i,
            w.value("SCAN", "completedSteps.value"),
            w.value("SCAN", "state.value"),
            w.value("COUNTER", "counter.value"),
            w.events,
        )
        for i, w in enumerate(watchers)
        if not final_seen(w, run)
    ]


def test_fifty_clients_see_the_final_values_and_memory_is_flat(demo):
    control = demo.context()
    rss = []
    for run in range(RUNS):
        watchers: list[Watcher] = []
        try:
            # connected one after another: p4p's server listens with a
            # backlog of 4, and a burst of 50 connects here sees SYN
            # retransmits of up to 15 s (a bare p4p server too)
            for _ in range(CLIENTS):
                watchers.append(Watcher(demo))
                wait_until(
                    lambda w=watchers[-1]: len(w.last) == len(MRIS),
                    what=lambda w=watchers[-1], r=run: (r, sorted(w.last), w.events),
                )
            control.put("COUNTER.counter", run, timeout=10)
            generator = demo_generator(ny=3, nx=10, duration=0.005)
            call(control, "configure", {"generator": generator})
            call(control, "run")
            final = control.get("SCAN", timeout=10)
            assert final["state.value"] == "Finished"
            assert final["completedSteps.value"] == STEPS
            wait_until(
                lambda w=watchers, r=run: all(final_seen(x, r) for x in w),
                what=lambda w=watchers, r=run: lagging(w, r),
            )
            for w in watchers:
                assert (
                    w.value("DET1", "completedSteps.value")
                    == (control.get("DET1.completedSteps", timeout=10)["value"])
                )
            call(control, "reset")
        finally:
            with ThreadPoolExecutor(10) as pool:
                list(pool.map(Watcher.close, watchers))
        time.sleep(RELEASE_DELAY + 0.5)  # channels nobody uses are let go
        rss.append(rss_kib(demo.proc.pid))
    print("server RSS after each run (KiB):", rss)
    # flat: the last run grows the server by less than 2 MiB
    assert rss[-1] - rss[-2] < 2048, rss


@pytest.fixture
def searching():
    """A client searching for HELLO before the server starts."""
    import socket

    from p4p.client.thread import Context

    from .conftest import client_conf, free_port

    udp = free_port(socket.SOCK_DGRAM)
    ctx = Context("pva", conf=client_conf(udp), useenv=False, nt=False)
    yield ctx, udp
    ctx.close()


def test_a_client_searching_during_start_up_finds_the_block(searching):
    ctx, udp = searching
    got: list[Any] = []

    def search() -> None:
        try:
            got.append(ctx.get("HELLO", timeout=20)["state.value"])
        except Exception as e:
            got.append(e)

    thread = threading.Thread(target=search)
    thread.start()
    time.sleep(0.5)  # searching already
    served = launch("demo", udp_port=udp)
    try:
        wait_ready(served)
        thread.join(25)
        assert got and got[0] in ("Disabled", "Resetting", "Ready"), got
    finally:
        served.stop()

"""Issue 9's pvAccess benchmarks: the served demo beside a bare p4p server
doing the same, in one run on this machine, as ratios with the targets.

    .venv/bin/python -m benchmarks.pva [--ops 600] [--per-round 10] [--no-load]

Run it under ``../shared/tools/isolated`` (it serves on free loopback ports).

- served: the demo process in this process (a ThreadedProcess) with
  :func:`malcolm.io.pva.start_pva_server`; bare: a p4p server in this
  process with a SharedPV per name, values of the very same types, whose
  handlers answer in p4p's thread: a greet RPC on a channel holding the
  method's structure that, as a served call does, posts ``took`` and
  ``returned`` there (one update, as the served greet, which does not
  wait) before answering; a put that checks the number and
  posts it with a timeStamp to the field's and the block's channels.
- the floor of the call and put ratios: the bare server again (names L.*)
  whose handlers hand the same work to the process's idle loop and answer
  there, as any server that keeps its state on an asyncio loop must: what
  the hop from p4p's thread to the loop costs, with none of malcolm's work;
- one p4p client Context each; ``--ops`` round trips a side of a method
  call (HELLO.greet), a put of COUNTER.counter, a get of it, a get of the
  whole COUNTER block, in short rounds of ``--per-round`` (10) a side
  taking turns (see
  ``timed``): the malcolm and bare columns are the medians of all round
  trips, the ratio the median of the rounds' ratios (each round's median
  over the bare server's in that round), the middle half of those ratios
  (their quartiles) beside it: how sure the figure is on a machine whose
  load changes from one second to the next;
- counter increments a second seen by a monitor (the target, in the issue's
  words): the value set as fast as the server side can (on the process's
  loop; bare: a thread posting), how far the value a monitor in a process of
  its own sees advances a second; beside it, not a target, the updates a
  second that monitor received (fewer than the increments where pvAccess
  squashes updates the client has not read yet); served and bare take
  turns, 6 rounds of 0.5 s each (see monitor_rates);
- monitor updates per change: puts one after another, updates counted (by
  a monitor whose queue holds them all, so none is squashed client-side);
- start to first get: ``python -m malcolm demo --pva-port P`` launched
  until a client's get of HELLO succeeds, a new client each attempt
  (median of 3). malcolm's modules are byte-compiled first (``compileall``,
  as ``pip install`` does): with ``PYTHONDONTWRITEBYTECODE`` set, as in this
  project's sessions, every launch would otherwise compile all of malcolm
  from source (about 0.1-0.3 s here), a cost no installed malcolm pays;
- server RSS: the load of tests/system (50 clients monitoring every demo
  block through a scan) three times against a served demo, its RSS after
  each (skip with ``--no-load``): the demo as it starts by default
  (pvAccess and the web server, whose aiohttp alone is about 12 MiB here),
  then with ``--web-port 0`` (the pvAccess server's own figure).
"""

from __future__ import annotations

import argparse
import asyncio
import compileall
import os
import signal
import socket
import statistics
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from p4p import Type, Value
from p4p.client.thread import Context
from p4p.server import Server, StaticProvider
from p4p.server.raw import SharedPV

from malcolm.demo import demo_generator, demo_process
from malcolm.embed import start_process
from malcolm.embed.loop import loop_name
from malcolm.io.pva import start_pva_server
from malcolm.io.pva.convert import to_value

ROOT = Path(__file__).resolve().parents[1]
WIDTH = 44


def free_port(kind: int = socket.SOCK_STREAM) -> int:
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def server_conf(udp: int) -> dict[str, str]:
    return {
        "EPICS_PVAS_INTF_ADDR_LIST": "127.0.0.1",
        "EPICS_PVAS_BROADCAST_PORT": str(udp),
        "EPICS_PVAS_BEACON_ADDR_LIST": f"127.0.0.1:{udp}",
        "EPICS_PVAS_AUTO_BEACON_ADDR_LIST": "NO",
    }


def client(udp: int, tcp: int) -> Context:
    conf = {
        "EPICS_PVA_ADDR_LIST": f"127.0.0.1:{udp}",
        "EPICS_PVA_AUTO_ADDR_LIST": "NO",
        "EPICS_PVA_BROADCAST_PORT": str(free_port(socket.SOCK_DGRAM)),
        "EPICS_PVA_NAME_SERVERS": f"127.0.0.1:{tcp}",
    }
    return Context("pva", conf=conf, useenv=False, nt=False)


def now_stamp() -> dict[str, int]:
    t = time.time()
    return {"secondsPastEpoch": int(t), "nanoseconds": int(t % 1 * 1e9)}


class Bare:
    """A bare p4p server doing what the served demo does, on names B.*

    With ``loop``, its put and rpc handlers hand the same work to that
    asyncio loop (``loop.call_soon_threadsafe``) and answer there: what any
    server that changes its state on a loop only pays, with none of
    malcolm's work (the floor of the round-trip ratios)."""

    def __init__(
        self,
        block: dict[str, Any],
        greet: dict[str, Any],
        greet_type: Type,
        prefix: str = "B",
        loop: asyncio.AbstractEventLoop | None = None,
    ) -> None:
        self.loop = loop
        self.counter_type = to_value(block["counter"]).type()
        self.counter = SharedPV(handler=self, initial=to_value(block["counter"]))
        self.block = SharedPV(initial=to_value(block))
        self.block_type = to_value(block).type()
        # the method's channel holds the method's structure, as HELLO.greet
        self.method_type = to_value(greet).type()
        self.greet = SharedPV(handler=self, initial=to_value(greet))
        self.greet_type = greet_type
        udp = free_port(socket.SOCK_DGRAM)
        provider = StaticProvider(f"bare-{prefix}")
        provider.add(f"{prefix}.counter", self.counter)
        provider.add(prefix, self.block)
        provider.add(f"{prefix}.greet", self.greet)
        conf = {**server_conf(udp), "EPICS_PVAS_SERVER_PORT": "0"}
        self.server = Server(providers=[provider], conf=conf, useenv=False)
        self.tcp = int(self.server.conf()["EPICS_PVAS_SERVER_PORT"])
        self.udp = udp
        self.provider = provider

    def put(self, pv: SharedPV, op: Any) -> None:
        if self.loop is not None:  # the floor: answered on the loop
            self.loop.call_soon_threadsafe(self.do_put, pv, op)
        else:
            self.do_put(pv, op)

    def do_put(self, pv: SharedPV, op: Any) -> None:
        try:
            number = float(op.value()["value"])
        except (TypeError, ValueError) as e:
            op.done(error=f"BadValueError: {e}")
            return
        self.set(number)
        op.done()

    def set(self, number: float) -> None:
        """As a served block's attribute changes: its channel and the block's
        channel each get the value and timeStamp."""
        stamp = now_stamp()
        value = Value(self.counter_type)
        value["value"] = number
        value["timeStamp"] = stamp
        self.counter.post(value)
        whole = Value(self.block_type)
        whole["counter.value"] = number
        whole["counter.timeStamp"] = stamp
        self.block.post(whole)

    def rpc(self, pv: SharedPV, op: Any) -> None:
        if self.loop is not None:
            self.loop.call_soon_threadsafe(self.do_rpc, pv, op)
        else:
            self.do_rpc(pv, op)

    def do_rpc(self, pv: SharedPV, op: Any) -> None:
        """As a served method call that does not wait: its channel gets
        ``took`` (the arguments, defaults filled) and ``returned``, two
        MethodLogs in one update (docs/core.md: one batch), then the answer."""
        name = op.value()["name"]
        update = Value(self.method_type)
        self.log(update, "took", {"name": name, "sleep": 0.0})
        greeting = f"Hello {name}"
        self.log(update, "returned", {"greeting": greeting})
        pv.post(update)
        op.done(Value(self.greet_type, {"greeting": greeting}))

    def log(self, update: Value, which: str, value: dict[str, Any]) -> None:
        update[which] = {
            "value": value,
            "present": list(value),
            "alarm": {"severity": 0, "status": 0, "message": ""},
            "timeStamp": now_stamp(),
        }

    def stop(self) -> None:
        self.server.stop()


def timed(
    funcs: list[Callable[[], Any]], ops: int, per_round: int = 10
) -> tuple[list[float], list[list[float]]]:
    """Each of ``funcs`` timed ``ops`` times (after 20 warm-ups) in short
    rounds of ``per_round`` calls each, the funcs taking turns in every
    round (which goes first rotates): ``(medians, rounds)``, the median
    seconds of each over all its calls, and for each round the median of
    each func's calls in it. A round is a fraction of a second, so a change
    of the machine's load (shared here) weighs on every func of a round
    alike: a ratio of two funcs is best read as the median of its per-round
    ratios (:func:`round_ratios`), their quartiles saying how sure it is."""
    for _ in range(20):
        for func in funcs:
            func()
    times: list[list[float]] = [[] for _ in funcs]
    rounds: list[list[float]] = []
    for n in range(max(1, ops // per_round)):
        medians = [0.0] * len(funcs)
        for i in range(len(funcs)):
            k = (i + n) % len(funcs)  # who goes first rotates
            func, out = funcs[k], []
            for _ in range(per_round):
                t0 = time.perf_counter()
                func()
                out.append(time.perf_counter() - t0)
            times[k] += out
            medians[k] = statistics.median(out)
        rounds.append(medians)
    return [statistics.median(t) for t in times], rounds


def round_ratios(rounds: list[list[float]], a: int, b: int) -> list[float]:
    """Per round, func ``a``'s median over func ``b``'s."""
    return [r[a] / r[b] for r in rounds]


def spread(ratios: list[float]) -> tuple[float, float, float]:
    """``(median, first quartile, third quartile)`` of per-round ratios."""
    if len(ratios) < 2:
        return ratios[0], ratios[0], ratios[0]
    q1, median, q3 = statistics.quantiles(ratios, n=4, method="inclusive")
    return median, q1, q3


# the monitor of monitor_rates, in a process of its own (see monitor_rates):
# each "start <first value>" line begins a count, each "stop" ends it and
# prints "<updates> <seconds> <increments> <seconds>": the updates received in
# the window and its length, and how far the counter advanced from the
# window's first update of this round (a value >= the round's first) to its
# last, and the time between those two; an empty line ends it
MONITOR = """
import sys, threading, time
from p4p.client.thread import Context
udp, tcp, name = sys.argv[1:]
ctx = Context("pva", useenv=False, nt=False, conf={
    "EPICS_PVA_ADDR_LIST": "127.0.0.1:" + udp, "EPICS_PVA_AUTO_ADDR_LIST": "NO",
    "EPICS_PVA_NAME_SERVERS": "127.0.0.1:" + tcp})
seen = [0, 0.0, 0.0]  # updates, the last value, when it came
first = threading.Event()
def on_update(value):
    seen[:] = seen[0] + 1, value["value"], time.perf_counter()
    first.set()
sub = ctx.monitor(name, on_update)
first.wait(10)
print("ready", flush=True)
line = sys.stdin.readline().split()
while line[:1] == ["start"]:
    base, before, t0 = float(line[1]), seen[0], time.perf_counter()
    while seen[1] < base and time.perf_counter() - t0 < 5:  # this round's first
        time.sleep(0.0005)
    v0, w0 = seen[1], seen[2]
    sys.stdin.readline()
    t1 = time.perf_counter()
    print(seen[0] - before, t1 - t0, seen[1] - v0, seen[2] - w0, flush=True)
    line = sys.stdin.readline().split()
sub.close()
ctx.close()
"""

#: sets the counter to start, start + 1, ... as fast as it can until the event
Spin = Callable[[threading.Event, int], None]

#: the first value of each round of monitor_rates is a multiple of this
ROUND_STEP = 10**8


def monitor_rates(
    sides: list[tuple[int, int, str, Spin]], rounds: int = 6, seconds: float = 0.5
) -> list[tuple[float, float]]:
    """For each side, ``(increments/s, updates/s)`` that a monitor of its
    name sees while its ``spin`` sets it, the sides taking turns for
    ``rounds`` rounds of ``seconds`` (a machine whose load changes weighs on
    both alike).

    The two figures measure different things. Increments a second (how far
    the counter's value advanced between the monitor's first and last update
    of a round, over the time between them) is the issue's figure, "counter
    increments per second seen by a monitor": how fast the server makes and
    sends changes that a client can follow. Updates a second counts what the
    monitor received: when the server posts faster than the client reads,
    pvAccess squashes the waiting updates into one (the client sees the
    latest value, fewer updates), so it is limited by the client on a fast
    side and by the server on a slow one.

    Each monitor is a client in a process of its own, as GDA is: in the
    server's process its callbacks would compete for the GIL with the
    thread that sets the counter, and it would count how often it got the
    GIL, not what the server sends."""
    monitors = []
    try:
        for udp, tcp, name, _ in sides:
            mon = subprocess.Popen(
                [sys.executable, "-c", MONITOR, str(udp), str(tcp), name],
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                text=True,
            )
            monitors.append(mon)
            assert mon.stdin is not None and mon.stdout is not None
            if mon.stdout.readline().strip() != "ready":
                raise RuntimeError(f"the monitor of {name} did not connect")
        time.sleep(0.2)
        # per side: updates, their seconds, increments, their seconds
        counts = [[0.0, 0.0, 0.0, 0.0] for _ in sides]
        for n in range(rounds):
            start = (n + 1) * ROUND_STEP  # above any value of an earlier round
            for (_, _, _, spin), mon, count in zip(sides, monitors, counts):
                assert mon.stdin is not None and mon.stdout is not None
                stop = threading.Event()
                worker = threading.Thread(target=spin, args=(stop, start))
                mon.stdin.write(f"start {start}\n")
                mon.stdin.flush()
                worker.start()
                time.sleep(seconds)
                mon.stdin.write("stop\n")
                mon.stdin.flush()
                stop.set()
                worker.join()
                figures = mon.stdout.readline().split()
                for i, figure in enumerate(figures):
                    count[i] += float(figure)
                time.sleep(0.05)  # the last updates drain
        return [(inc / inc_s, upd / upd_s) for upd, upd_s, inc, inc_s in counts]
    finally:
        for mon in monitors:
            mon.kill()
        for mon in monitors:
            mon.wait(60)  # a loaded machine (shared here) can take a while


def updates_per_change(ctx: Context, name: str, puts: int) -> float:
    seen = [0]
    first = threading.Event()

    def on_update(_value: Any) -> None:
        seen[0] += 1
        first.set()

    # a queue that holds every update: a client that falls behind (here,
    # its callbacks waiting for the GIL) gets updates squashed into one by
    # pvAccess; this figure counts what the server sends per change
    sub = ctx.monitor(name, on_update, request=f"record[queueSize={2 * puts}]")
    first.wait(5)
    time.sleep(0.3)
    before = seen[0]
    for n in range(puts):
        ctx.put(name, 1000.0 + n, timeout=5)
    time.sleep(0.5)
    sub.close()
    return (seen[0] - before) / puts


def served_spin(process: Any) -> Spin:
    # the attribute, as the part that owns it holds it (a look-up through the
    # block's __getattr__ costs about 0.8 us here, no part pays it per change)
    counter = process.get_block("COUNTER").counter

    async def spin(stop: threading.Event, start: int) -> None:
        n = start - 1
        while not stop.is_set():
            for _ in range(100):
                n += 1
                counter.set_value(float(n))
            await asyncio.sleep(0)

    return lambda stop, start: process.call_threadsafe(spin, stop, start).result()


def bare_spin(bare: Bare) -> Spin:
    def spin(stop: threading.Event, start: int) -> None:
        n = start - 1
        while not stop.is_set():
            for _ in range(100):
                n += 1
                bare.set(float(n))
            time.sleep(0)

    return spin


def launch_demo(*extra: str) -> tuple[subprocess.Popen[str], int, int]:
    """``malcolm demo`` serving pvAccess on a free port (and, by default, the
    web on 8008: ``extra`` ``--web-port 0`` turns it off)."""
    tcp, udp = free_port(), free_port(socket.SOCK_DGRAM)
    env = dict(os.environ, **server_conf(udp))
    proc = subprocess.Popen(
        [sys.executable, "-m", "malcolm", "demo", "--pva-port", str(tcp), *extra],
        cwd=ROOT,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    return proc, tcp, udp


def start_to_first_get() -> float:
    """Seconds from launching ``malcolm demo`` to a get of HELLO that works.

    Each attempt is a new client: one client retrying would measure its own
    back-off (p4p waits about a second before searching again after a miss
    or a refused connection), not when the server could first answer."""
    t0 = time.perf_counter()
    proc, tcp, udp = launch_demo()
    try:
        while True:
            try:
                ctx = client(udp, tcp)
            except RuntimeError:  # its free UDP port taken meanwhile: another
                continue
            try:
                ctx.get("HELLO", timeout=0.05)
                return time.perf_counter() - t0
            except Exception:
                if time.perf_counter() - t0 > 30:
                    raise
            finally:
                ctx.close()
    finally:
        proc.send_signal(signal.SIGINT)
        proc.wait(20)


def rss_mib(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def load_rss(*extra: str, runs: int = 3, clients: int = 50) -> list[float]:
    """The served demo's RSS after each of ``runs`` loads (``extra``: more
    arguments of ``malcolm demo``)."""
    mris = ["HELLO", "COUNTER", "MOTOR:X", "MOTOR:Y", "DET1", "DET2", "SCAN"]
    proc, tcp, udp = launch_demo(*extra)
    control = client(udp, tcp)
    out = []
    try:
        control.get("HELLO", timeout=30)
        for _ in range(runs):
            contexts, subs = [], []
            for _ in range(clients):
                ctx = client(udp, tcp)
                got = threading.Semaphore(0)
                subs += [ctx.monitor(m, lambda v, g=got: g.release()) for m in mris]
                for _ in mris:
                    got.acquire(timeout=30)
                contexts.append(ctx)
            gen = demo_generator(ny=3, nx=10, duration=0.005)
            control.rpc("SCAN.configure", to_value({"generator": gen}), timeout=60)
            control.rpc("SCAN.run", Value(Type([]), {}), timeout=60)
            control.rpc("SCAN.reset", Value(Type([]), {}), timeout=60)
            for sub in subs:
                sub.close()
            for ctx in contexts:
                ctx.close()
            time.sleep(3)
            out.append(rss_mib(proc.pid))
    finally:
        control.close()
        proc.send_signal(signal.SIGINT)
        proc.wait(20)
    return out


def row(
    case: str,
    malcolm: float,
    bare: float,
    target: str,
    ok: bool,
    ratio: float | None = None,
    quartiles: tuple[float, float] | None = None,
) -> str:
    if ratio is None:
        ratio = malcolm / bare if bare else float("nan")
    verdict = "ok" if ok else "MISSED"
    if quartiles is not None:
        verdict = (
            f"{verdict:<8}(rounds' middle half: {quartiles[0]:.2f}-{quartiles[1]:.2f})"
        )
    return (
        f"{case:<{WIDTH}}{malcolm:>10.4g}{bare:>10.4g}{ratio:>8.2f}"
        f"  {target:<16}{verdict}"
    )


def serve_demo() -> tuple[Any, Any, Any, int, int]:
    """The demo process started in a thread of this one (a ThreadedProcess)
    and served on free loopback ports: the process, its thread, the pvAccess
    server and the server's UDP and TCP ports."""
    process = demo_process()
    tp = start_process(process)
    udp = free_port(socket.SOCK_DGRAM)
    served = process.call_threadsafe(
        start_pva_server, process, 0, server_conf(udp)
    ).result(10)
    return process, tp, served, udp, int(served.address.rsplit(":", 1)[1])


def main(ops: int = 600, load: bool = True, per_round: int = 10) -> None:
    process, tp, served, udp, tcp = serve_demo()
    m = client(udp, tcp)
    greet_type = m.rpc(
        "HELLO.greet", Value(Type([("name", "s")]), {"name": "x"}), timeout=5
    ).type()
    structures = (process.get(["COUNTER"]), process.get(["HELLO", "greet"]))
    bare = Bare(*structures, greet_type)
    b = client(bare.udp, bare.tcp)
    floor = Bare(*structures, greet_type, prefix="L", loop=process.loop)
    f = client(floor.udp, floor.tcp)
    args = Value(Type([("name", "s")]), {"name": "bench"})
    lines = [
        f"{'figure':<{WIDTH}}{'malcolm':>10}{'bare':>10}{'ratio':>8}  "
        f"{'target':<16}verdict"
    ]
    try:
        pairs = [
            ("method call round trip (ms)", "HELLO.greet", "B.greet", "call"),
            ("put of one field (ms)", "COUNTER.counter", "B.counter", "put"),
            ("get of one field (ms)", "COUNTER.counter", "B.counter", "get"),
            ("get of a whole block (ms)", "COUNTER", "B", "get"),
        ]
        for case, mine, theirs, kind in pairs:
            names = [mine, theirs, theirs.replace("B", "L", 1)]
            if kind == "call":
                funcs = [
                    lambda c=c, n=n: c.rpc(n, args, timeout=5)
                    for c, n in zip((m, b, f), names)
                ]
            elif kind == "put":
                funcs = [
                    lambda c=c, n=n: c.put(n, 3.0, timeout=5)
                    for c, n in zip((m, b, f), names)
                ]
            else:
                funcs = [
                    lambda c=c, n=n: c.get(n, timeout=5) for c, n in zip((m, b), names)
                ]
            (fm, fb, *fl), rounds = timed(funcs, ops, per_round)
            ratio, q1, q3 = spread(round_ratios(rounds, 0, 1))
            lines.append(
                row(
                    case,
                    fm * 1e3,
                    fb * 1e3,
                    "<= 1.2x bare",
                    ratio <= 1.2,
                    ratio,
                    (q1, q3),
                )  # fmt: skip
            )
            # (rows: case, its time, the time beside it, their rounds, note)
            below = (
                ("  bare, answered on an asyncio loop", fl[0], fb, 2, 1, "(the floor)"),
                ("  malcolm over the floor", fm, fl[0], 0, 2, "(its own work)"),
            ) if fl else ()  # fmt: skip
            for case, one, other, top, under, note in below:
                ratio, q1, q3 = spread(round_ratios(rounds, top, under))
                lines.append(
                    f"{case:<{WIDTH}}{one * 1e3:>10.4g}{other * 1e3:>10.4g}"
                    f"{ratio:>8.2f}  {note:<16}-       "
                    f" (rounds' middle half: {q1:.2f}-{q3:.2f})"
                )
        (im, rm), (ib, rb) = monitor_rates(
            [
                (udp, tcp, "COUNTER.counter", served_spin(process)),
                (bare.udp, bare.tcp, "B.counter", bare_spin(bare)),
            ]
        )
        lines.append(
            row(
                "counter increments/s seen by a monitor",
                im,
                ib,
                ">= 0.8x bare",
                im >= 0.8 * ib,
            )  # fmt: skip
        )
        case = "  updates/s the monitor received"
        lines.append(
            f"{case:<{WIDTH}}{rm:>10.4g}{rb:>10.4g}{rm / rb:>8.2f}  "
            f"{'(not a target)':<16}-"
        )
        um = updates_per_change(m, "COUNTER.counter", 100)
        ub = updates_per_change(b, "B.counter", 100)
        lines.append(row("monitor updates per change", um, ub, "exactly 1", um == 1.0))
    finally:
        m.close()
        b.close()
        f.close()
        bare.stop()
        floor.stop()
        process.call_threadsafe(served.close).result(10)
        tp.stop()
    compileall.compile_dir(ROOT / "malcolm", quiet=1)
    start = statistics.median(start_to_first_get() for _ in range(3))
    lines.append(
        f"{'process start to first get (s)':<{WIDTH}}{start:>10.3f}{'-':>10}"
        f"{'-':>8}  {'<= 0.8 s':<16}{'ok' if start <= 0.8 else 'MISSED'}"
    )
    if load:
        for case, extra in (
            ("server RSS after the load test (MiB)", ()),
            ("  the same, pvAccess only (--web-port 0)", ("--web-port", "0")),
        ):
            rss = load_rss(*extra)
            flat = rss[-1] - rss[-2] < 2
            lines.append(
                f"{case:<{WIDTH}}{rss[-1]:>10.1f}{'-':>10}{'-':>8}  "
                f"{'<= 60, flat':<16}{'ok' if rss[-1] <= 60 and flat else 'MISSED'}"
                f"  (runs: {', '.join(f'{r:.1f}' for r in rss)})"
            )
    one, five, fifteen = os.getloadavg()
    lines.append(
        "(ratio = malcolm / bare; of a round trip: the median of per-round"
        f" ratios ({ops // per_round} rounds of {per_round} calls a side), the"
        f" middle half of them beside it; machine: {os.cpu_count()} cores, load average"
        f" {one:.2f} {five:.2f} {fifteen:.2f}; the process's loop (and the"
        f" floor's): {loop_name()}; reference: 7.5x bare on a method"
        " call, 2 updates per change)"
    )
    print("\n".join(lines))


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ops", type=int, default=600)
    parser.add_argument("--per-round", type=int, default=10)
    parser.add_argument("--no-load", action="store_true")
    a = parser.parse_args()
    main(a.ops, not a.no_load, a.per_round)

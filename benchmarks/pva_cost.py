"""The Python work of one served pvAccess operation, counted: a figure the
machine's load does not move (benchmarks.pva's times do, on a shared one).

    .venv/bin/python -m benchmarks.pva_cost [--functions]

Run it under ``../shared/tools/isolated`` (it serves on free loopback ports).
For a method call (HELLO.greet), a put of COUNTER.counter and a change of
the counter (its field's and its block's channels open, as in
benchmarks.pva), the Python bytecodes executed and the Python functions
entered (``sys.settrace``'s opcode and call events) on the process's loop,
from the handler p4p's hand-over runs to its return; beside them the bare
server of benchmarks.pva doing the same (its handler's, or its ``set``'s).
C work (p4p, pvxs, the interpreter's builtins) is not counted: these say
how much Python a figure of benchmarks.pva pays, which is what this server
can change (cold, between two client requests, each bytecode costs several
times what it costs in a tight loop). ``--functions`` adds, for each row,
the opcodes executed in each function (its own, not its callees').
"""

from __future__ import annotations

import collections
import concurrent.futures
import sys
from collections.abc import Callable
from types import FrameType
from typing import Any

from p4p import Type, Value

from .pva import WIDTH, Bare, client, serve_demo


class Op:
    """What a put or call handler uses of p4p's ServerOperation."""

    def __init__(self, value: Value, request: Value) -> None:
        self._value, self._request = value, request

    def value(self) -> Value:
        return self._value

    def pvRequest(self) -> Value:  # noqa: N802 (p4p's name)
        return self._request

    def done(self, value: Any = None, error: str | None = None) -> None:
        if error is not None:
            raise RuntimeError(error)


def counted(
    loop: Any,
    func: Callable[[], Any],
    warm: int = 50,
    by_function: collections.Counter[str] | None = None,
) -> tuple[int, int]:
    """``(opcodes, calls)`` of one ``func()`` run as a loop callback (as the
    hand-over runs a handler), after ``warm`` runs; the least of 5.
    ``by_function`` is given the opcodes of that run by function."""

    def run_on_loop(target: Callable[[], Any]) -> Any:
        fut: concurrent.futures.Future[Any] = concurrent.futures.Future()
        loop.call_soon_threadsafe(lambda: fut.set_result(target()))
        return fut.result(30)

    for _ in range(warm):
        run_on_loop(func)
    count = [0, 0]
    functions: collections.Counter[str] = collections.Counter()

    def tracer(frame: FrameType, event: str, arg: Any) -> Any:
        frame.f_trace_opcodes = True
        if event == "opcode":
            count[0] += 1
            code = frame.f_code
            functions[
                f"{code.co_qualname} ({code.co_filename.rsplit('/', 1)[-1]})"
            ] += 1
        elif event == "call":
            count[1] += 1
        return tracer

    def traced() -> tuple[int, int, dict[str, int]]:
        count[:] = [0, 0]
        functions.clear()
        sys.settrace(tracer)
        try:
            func()
        finally:
            sys.settrace(None)
        return count[0], count[1], dict(functions)

    opcodes, calls, least = min(run_on_loop(traced) for _ in range(5))
    if by_function is not None:
        by_function.update(least)
    return opcodes, calls


def main(functions: bool = False) -> None:
    process, tp, served, udp, tcp = serve_demo()
    loop = process.loop
    ctx = client(udp, tcp)
    args = Value(Type([("name", "s")]), {"name": "bench"})
    greet_type = ctx.rpc("HELLO.greet", args, timeout=5).type()
    ctx.put("COUNTER.counter", 3.0, timeout=5)
    ctx.get("COUNTER", timeout=5)  # the block's channel open too
    put_value = ctx.get("COUNTER.counter", timeout=5)
    put_value = Value(put_value.type(), {"value": 4.0})
    put_value.mark("value")
    request = Value(Type([]), {})
    structures = (process.get(["COUNTER"]), process.get(["HELLO", "greet"]))
    bare = Bare(*structures, greet_type)
    try:
        greet = served._channels["HELLO.greet"]
        counter_channel = served._channels["COUNTER.counter"]
        counter = process.get_block("COUNTER").counter
        call_op, put_op = Op(args, request), Op(put_value, request)
        number = [0.0]

        def change() -> None:
            number[0] += 1
            counter.set_value(number[0])

        def bare_change() -> None:
            number[0] += 1
            bare.set(number[0])

        rows = [
            (
                "method call",
                lambda: greet.handler.rpc(greet.pv, call_op),
                lambda: bare.do_rpc(bare.greet, call_op),
            ),
            (
                "put of one field",
                lambda: counter_channel.handler.put(counter_channel.pv, put_op),
                lambda: bare.do_put(bare.counter, put_op),
            ),
            ("a change, two channels open", change, bare_change),
        ]
        lines = [
            f"{'Python work per operation':<{WIDTH}}{'malcolm':>10}{'bare':>10}"
            f"{'ratio':>8}  (not a target)"
        ]
        detail: list[str] = []
        for case, mine, theirs in rows:
            per: collections.Counter[str] = collections.Counter()
            (mo, mc), (bo, bc) = (
                counted(loop, mine, by_function=per),
                counted(loop, theirs),
            )
            for what, m, b in (("opcodes", mo, bo), ("calls", mc, bc)):
                name = f"{case}: {what}"
                lines.append(f"{name:<{WIDTH}}{m:>10}{b:>10}{m / b:>8.2f}")
            detail.append(f"\n{case}, malcolm's opcodes by function:")
            detail += [f"{n:>6}  {where}" for where, n in per.most_common()]
        print("\n".join(lines + (detail if functions else [])))
    finally:
        ctx.close()
        bare.stop()
        process.call_threadsafe(served.close).result(10)
        tp.stop()


if __name__ == "__main__":
    main(functions="--functions" in sys.argv[1:])

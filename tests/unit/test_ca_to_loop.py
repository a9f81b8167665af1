"""io/ca/backend.py's to_loop: what libca's threads hand to the loop (the
short road: one call_soon_threadsafe, no Future)."""

from __future__ import annotations

import asyncio
import threading

from malcolm.io.ca.backend import _Inbox, to_loop


def test_on_the_loop_thread_it_runs_at_once() -> None:
    async def scenario() -> list[int]:
        ran: list[int] = []
        to_loop(asyncio.get_running_loop(), ran.append, 1)
        return ran  # before any await: at once

    assert asyncio.run(scenario()) == [1]


def test_from_another_thread_it_runs_on_the_loop_in_order() -> None:
    async def scenario() -> list[tuple[int, bool]]:
        loop = asyncio.get_running_loop()
        loop_thread = threading.get_ident()
        ran: list[tuple[int, bool]] = []
        done = asyncio.Event()

        def record(i: int) -> None:
            ran.append((i, threading.get_ident() == loop_thread))
            if i == 9:
                done.set()

        def library_thread() -> None:
            for i in range(10):
                to_loop(loop, record, i)

        thread = threading.Thread(target=library_thread)
        thread.start()
        await asyncio.wait_for(done.wait(), 5)
        thread.join()
        return ran

    assert asyncio.run(scenario()) == [(i, True) for i in range(10)]


def test_a_closed_loop_is_told_nothing() -> None:
    loop = asyncio.new_event_loop()
    loop.close()
    ran: list[int] = []
    thread = threading.Thread(target=to_loop, args=(loop, ran.append, 1))
    thread.start()
    thread.join()
    assert ran == []


def test_a_burst_from_a_thread_wakes_the_loop_once_and_keeps_its_order() -> None:
    async def scenario() -> tuple[list[int], int]:
        loop = asyncio.get_running_loop()
        wakeups = [0]
        hop = loop.call_soon_threadsafe

        def counting(*args: object) -> object:
            wakeups[0] += 1
            return hop(*args)  # type: ignore[arg-type]

        loop.call_soon_threadsafe = counting  # type: ignore[method-assign]
        ran: list[int] = []
        done = asyncio.Event()

        def record(i: int) -> None:
            ran.append(i)
            if i == 999:
                done.set()

        def failing(i: int) -> None:
            raise RuntimeError(f"event {i} handled badly")

        def library_thread() -> None:
            for i in range(1000):
                to_loop(loop, failing if i == 500 else record, i)

        # the loop does not run while the thread hands its burst over
        thread = threading.Thread(target=library_thread)
        thread.start()
        thread.join()
        await asyncio.wait_for(done.wait(), 5)
        loop.call_soon_threadsafe = hop  # type: ignore[method-assign]
        return ran, wakeups[0]

    ran, wakeups = asyncio.run(scenario())
    # every one, in order (a failing one logged, the rest still run)
    assert ran == [i for i in range(1000) if i != 500]
    assert wakeups == 1


def test_what_comes_while_the_loop_takes_a_batch_runs_after_its_other_work() -> None:
    async def scenario() -> list[str]:
        loop = asyncio.get_running_loop()
        order: list[str] = []
        done = asyncio.Event()
        late = threading.Event()

        def first() -> None:
            order.append("first")
            # more arrives from the library while the batch runs
            threading.Thread(target=to_loop, args=(loop, second)).start()
            late.wait(5)
            loop.call_soon(order.append, "other")

        def second() -> None:
            order.append("second")
            done.set()

        def hand_over() -> None:
            to_loop(loop, first)

        original = _Inbox.put

        def put(self: _Inbox, func: object, args: tuple[object, ...]) -> None:
            original(self, func, args)  # type: ignore[arg-type]
            if func is second:
                late.set()

        _Inbox.put = put  # type: ignore[method-assign]
        try:
            threading.Thread(target=hand_over).start()
            await asyncio.wait_for(done.wait(), 5)
        finally:
            _Inbox.put = original  # type: ignore[method-assign]
        return order

    assert asyncio.run(scenario()) == ["first", "other", "second"]


def test_a_backend_without_its_own_put_and_read_puts_then_gets() -> None:
    from malcolm.io import SoftBackend

    async def scenario() -> tuple[float, float]:
        backend = SoftBackend()
        backend.define("T:X_RBV", 0.0, follow=lambda v: round(v, 2))
        channel = backend.channel("T:X_RBV", "T:X")
        await channel.connect(1)
        reading = await channel.put_and_read(0.1234)
        await backend.close()
        return reading.value, 0.12

    got, want = asyncio.run(scenario())
    assert got == want

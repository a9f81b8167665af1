"""io/ca/backend.py's to_loop: what libca's threads hand to the loop (the
short road: one call_soon_threadsafe, no Future)."""

from __future__ import annotations

import asyncio
import threading

from malcolm.io.ca.backend import to_loop


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

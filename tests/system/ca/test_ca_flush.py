"""Gets and puts made on the loop are sent together at the end of its turn
(io/ca/link.py's flush_soon), and still in order: a get made after a put
reads what the put left, against the simulated IOC."""

from __future__ import annotations

import asyncio
from typing import Any

from malcolm.io.ca import link as ca_link
from malcolm.io.ca.backend import PyepicsBackend

from .conftest import PREFIX, run

PV = f"{PREFIX}:M2:ACCL"


def test_a_get_made_after_a_put_in_the_same_turn_reads_the_put(ioc, monkeypatch):
    flushes: list[int] = []
    flush = ca_link._flush

    def counted() -> None:
        flushes.append(1)
        flush()

    monkeypatch.setattr(ca_link, "_flush", counted)

    async def scenario() -> list[Any]:
        loop = asyncio.get_running_loop()
        channel = PyepicsBackend().channel(PV, PV, default=0.0)
        await channel.connect(5)
        pv = ca_link.link(PV)
        original = (await channel.get()).value
        seen = []
        try:
            for value in (0.25, 0.35, 0.45):
                put, got = loop.create_future(), loop.create_future()

                def answer(fut: asyncio.Future[Any]) -> Any:
                    return lambda p, e: loop.call_soon_threadsafe(fut.set_result, p)

                flushes.clear()
                # no await between: both go in the turn's one flush
                pv.put(value, answer(put))
                pv.get(answer(got))
                assert flushes == []  # not sent yet: at the end of the turn
                await asyncio.wait_for(asyncio.gather(put, got), 5)
                assert len(flushes) == 1
                seen.append(float(got.result()[0]))
        finally:
            await channel.put(original)
            await channel.close()
        return seen

    assert run(scenario()) == [0.25, 0.35, 0.45]

"""Every channel of one PV on a loop hears each event of the PV in one
loop callback (io/ca/backend.py's PVFanout), against the simulated IOC."""

from __future__ import annotations

import asyncio
from typing import Any

from malcolm.io.ca import backend as ca_backend
from malcolm.io.ca.backend import PyepicsBackend

from .conftest import PREFIX, run, until

PV = f"{PREFIX}:M1:ACCL"


def test_an_event_of_a_pv_reaches_all_its_channels_in_one_hop(ioc):
    async def scenario():
        # what libca's threads hand the loop (its inbox: to_loop), each
        # counted, however many wake-ups of the loop carry them
        hops: list[Any] = []
        hop = ca_backend._Inbox.put

        def counting(inbox: Any, func: Any, args: Any) -> None:
            hops.append(func)
            hop(inbox, func, args)

        backend = PyepicsBackend()
        first = backend.channel(PV, PV, default=0.0)
        await first.connect(5)
        original = (await first.get()).value  # the session IOC's: put back

        async def change(value: float) -> int:
            """Hops to the loop of a put and its event, all channels told."""
            ca_backend._Inbox.put = counting  # type: ignore[method-assign]
            hops.clear()
            await first.put(value)
            for channel in channels:
                await until(
                    lambda c=channel: c.latest is not None and c.latest.value == value,
                    what=f"{PV} = {value} reaching every channel",
                )
            await asyncio.sleep(0.2)  # any later hop of this change counts too
            ca_backend._Inbox.put = hop  # type: ignore[method-assign]
            return len(hops)

        channels = [first]
        try:
            alone = await change(0.3)
            channels += [backend.channel(PV, PV, default=0.0) for _ in range(3)]
            for channel in channels[1:]:
                await channel.connect(5)
                assert channel.latest is not None and channel.latest.value == 0.3
            # a task woken by the first channel's subscriber finds every other
            # channel of the PV given the same reading already
            behind: list[tuple[float, list[float]]] = []
            woken: asyncio.Queue[float] = asyncio.Queue()
            first.subscribe(lambda reading: woken.put_nowait(reading.value))

            async def check() -> None:
                while True:
                    value = await woken.get()
                    held = [c.latest.value for c in channels if c.latest]
                    behind.append((value, held))

            checking = asyncio.ensure_future(check())
            together = await change(0.4)
            checking.cancel()
        finally:
            ca_backend._Inbox.put = hop  # type: ignore[method-assign]
            await first.put(original)
            await backend.close()
        return alone, together, behind

    alone, together, behind = run(scenario())
    assert together == alone, (
        f"{together} hops to the loop for one change with 4 channels of the PV,"
        f" {alone} with one: each event should cross once"
    )
    # what the woken task found: every channel holding what woke it
    assert behind and behind[-1][0] == 0.4, behind
    assert all(held == [value] * 4 for value, held in behind), behind

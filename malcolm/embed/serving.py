"""Run a Process on the current asyncio loop: ``running``, ``serve`` and the
state-change log that ``serve`` writes (``watch_states``)."""

from __future__ import annotations

import asyncio
import logging
from collections.abc import AsyncIterator, Callable, Iterable
from contextlib import asynccontextmanager
from typing import Any

from malcolm.core import Process, Subscription, long_lived


@asynccontextmanager
async def running(process: Process) -> AsyncIterator[Process]:
    """``async with running(p):`` starts ``p`` on the current loop, then stops it."""
    await process.start()
    try:
        yield process
    finally:
        await process.stop()


def watch_states(
    process: Process, logger: logging.Logger | None = None
) -> list[Subscription]:
    """Log ``MRI: Old -> New`` for every state change of every block, and
    ``MRI: health: message`` when a block's health stops being OK.

    Subscribe before ``process.start()`` to see ``Disabled -> Resetting``.
    Returns the subscriptions (pass each to ``process.unsubscribe``).
    """
    logger = logger or logging.getLogger("malcolm.serve")
    subs = []
    for mri in process.mris:
        last: dict[str, Any] = {}

        def on_state(value: Any, mri: str = mri, last: dict[str, Any] = last) -> None:
            before = last.get("state")
            last["state"] = value
            if before is not None and value != before:
                logger.info("%s: %s -> %s", mri, before, value)

        def on_health(value: Any, mri: str = mri, last: dict[str, Any] = last) -> None:
            before = last.get("health")
            last["health"] = value
            if before is not None and value != before:
                level = logging.INFO if value == "OK" else logging.WARNING
                logger.log(level, "%s: health: %s", mri, value)

        block = process.get_block(mri)
        subs.append(process.subscribe([mri, "state", "value"], on_state, False))
        if "health" in block:
            subs.append(process.subscribe([mri, "health", "value"], on_health, False))
    return subs


async def serve(
    process: Process,
    ready: Callable[[Process], None] | None = None,
    signals: Iterable[int] | None = None,
    logger: logging.Logger | None = None,
    freeze: bool = False,
    pva_port: int = 0,
    web_port: int | None = None,
) -> None:
    """Start ``process`` on the current loop, logging state changes; run until
    one of ``signals`` (default SIGINT and SIGTERM) arrives, then stop it.
    ``pva_port`` (if not 0) serves its blocks over pvAccess on that port from
    before they start (docs/pva.md), logging the address.

    ``ready(process)`` is called once every block has started. ``freeze``
    starts the blocks under :func:`malcolm.core.long_lived` (for a process
    that serves until the program ends, as ``malcolm serve`` does).
    ``web_port`` (not 0 or None) serves it on the web too (docs/web.md).
    """
    import signal as _signal

    loop = asyncio.get_running_loop()
    stop = asyncio.Event()
    sigs = list(signals) if signals is not None else [_signal.SIGINT, _signal.SIGTERM]
    for sig in sigs:
        loop.add_signal_handler(sig, stop.set)
    subs = watch_states(process, logger)
    pva = None
    try:
        if pva_port:
            from malcolm.io.pva import start_pva_server
            from malcolm.io.pva.client_blocklist import add_block_list

            pva = await start_pva_server(process, pva_port)
            add_block_list(process)  # for malcolm ls (docs/pva-client.md)
            (logger or logging.getLogger("malcolm.serve")).info(
                "pvAccess: serving on %s", pva.address
            )
        if freeze:
            with long_lived():
                await process.start()
        else:
            await process.start()
        from malcolm.io.web.cli import start_if_asked

        web = await start_if_asked(process, web_port, "malcolm serve")
        if ready is not None:
            ready(process)
        try:
            await stop.wait()
        finally:
            if web is not None:
                await web.close()
        (logger or logging.getLogger("malcolm.serve")).info("stopping")
    finally:
        for sig in sigs:
            loop.remove_signal_handler(sig)
        try:
            if pva is not None:
                await pva.close()
            await process.stop()
        finally:
            for sub in subs:
                process.unsubscribe(sub)

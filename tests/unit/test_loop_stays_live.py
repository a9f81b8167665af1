"""Work of more than a few milliseconds runs off the loop (issue 8): while a
scan costly to build (a region over a big grid) is computed for configure()
or validate(), or a design is read or written, other blocks answer puts and
gets. A scan cheap to build is planned on the loop (the hop to a thread
would cost more).

Each test holds the slow work in its worker thread until the test has used
another block (an ordering check, no clock): were the work on the loop, the
loop could not run the test's put until it ended. The hold gives up after
HOLD seconds only so that a regression fails instead of hanging.
"""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Callable
from typing import Any

import pytest

import malcolm.editor.store as store_module
import malcolm.scan
from malcolm.core import AbortedError, Process
from malcolm.demo import demo_generator, demo_process
from malcolm.scan import cheap_to_build

HOLD = 5.0


class Held:
    """Wraps a function so that each call waits, in its thread, until
    ``release()``; ``entered`` is set when a call has begun, and ``order``
    gets "work done" when it ends."""

    def __init__(self, func: Callable[..., Any]) -> None:
        self.func = func
        self.entered = threading.Event()
        self.released = threading.Event()
        self.threads: list[str] = []
        self.order: list[str] = []

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        self.threads.append(threading.current_thread().name)
        self.entered.set()
        self.released.wait(HOLD)
        try:
            return self.func(*args, **kwargs)
        finally:
            self.order.append("work done")

    async def wait_entered(self) -> None:
        assert await asyncio.to_thread(self.entered.wait, HOLD), "never called"

    def release(self) -> None:
        self.released.set()


async def other_block_answers(process: Process, value: float, held: Held) -> None:
    """A put and a get of COUNTER complete before the held work has ended."""
    await process.put(["COUNTER", "counter"], value)
    assert process.get(["COUNTER", "counter", "value"]) == value
    held.order.append("other block answered")
    assert held.order == ["other block answered"]


def run(body: Callable[[Process], Any]) -> None:
    async def main() -> None:
        process = demo_process()
        await process.start()
        try:
            await body(process)
        finally:
            await process.stop()

    asyncio.run(main())


def costly_scan(ny: int, nx: int) -> dict[str, Any]:
    """A demo grid with a circle region on it: building it evaluates all
    ``ny * nx`` points, so it is planned in a worker thread."""
    generator = demo_generator(ny, nx, 0.001)
    generator["excluders"] = [
        {
            "typeid": "scanpointgenerator:excluder/ROIExcluder:1.0",
            "axes": ["x", "y"],
            "rois": [
                {
                    "typeid": "scanpointgenerator:roi/CircularROI:1.0",
                    "centre": [0.5, 0.5],
                    "radius": 0.5,
                }
            ],
        }
    ]
    assert not cheap_to_build(generator)
    return generator


@pytest.mark.parametrize("call", ["configure", "validate"])
def test_other_blocks_answer_while_scan_points_are_computed(
    monkeypatch: pytest.MonkeyPatch, call: str
) -> None:
    held = Held(malcolm.scan.scan_points)
    monkeypatch.setattr(malcolm.scan, "scan_points", held)
    # a scan no other test computed (their points are kept, by generator)
    generator = costly_scan(170, 190 if call == "configure" else 210)

    async def body(process: Process) -> None:
        pending = asyncio.ensure_future(
            process.post(["SCAN", call], {"generator": generator})
        )
        await held.wait_entered()
        await other_block_answers(process, 7, held)
        held.release()
        await pending
        if call == "configure":
            assert process.get(["SCAN", "state", "value"]) == "Armed"
            total = process.get(["SCAN", "totalSteps", "value"])
            assert 0 < total < 170 * 190  # the circle's points

    run(body)
    assert held.threads and threading.main_thread().name not in held.threads


def test_a_scan_cheap_to_build_is_planned_on_the_loop(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The hop to a worker thread costs more than building a small grid:
    configure() builds it on the loop (issue 7's configure target)."""
    import malcolm.scan.load  # noqa: F401  (the first scan is off the loop)

    calls = Held(malcolm.scan.scan_points)
    calls.release()  # nothing held: only where it runs is recorded
    monkeypatch.setattr(malcolm.scan, "scan_points", calls)
    generator = demo_generator(4, 7, 0.001)
    assert cheap_to_build(generator)

    async def body(process: Process) -> None:
        await process.post(["SCAN", "configure"], {"generator": generator})
        assert process.get(["SCAN", "totalSteps", "value"]) == 28

    run(body)
    assert calls.threads and set(calls.threads) == {threading.main_thread().name}


def test_other_blocks_answer_while_a_design_is_written(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    held = Held(store_module.atomic_write)
    monkeypatch.setattr(store_module, "atomic_write", held)

    async def body(process: Process) -> None:
        saving = asyncio.ensure_future(process.post(["SCAN", "save"], {"design": "a"}))
        await held.wait_entered()
        await other_block_answers(process, 3, held)
        held.release()
        await saving
        assert process.get(["SCAN", "design", "value"]) == "a"

    run(body)


def test_other_blocks_answer_while_a_design_is_read(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    held = Held(store_module.load_design)

    async def body(process: Process) -> None:
        await process.post(["SCAN", "save"], {"design": "b"})
        monkeypatch.setattr(store_module, "load_design", held)
        loading = asyncio.ensure_future(process.put(["SCAN", "design"], "b"))
        await held.wait_entered()
        await other_block_answers(process, 4, held)
        held.release()
        await loading
        assert process.get(["SCAN", "state", "value"]) == "Ready"

    run(body)


def test_a_save_interrupted_while_writing_is_seen_through(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """disable() during the write: the file is written and ``design`` says
    so (all, not half), then the manager is disabled."""
    held = Held(store_module.atomic_write)
    monkeypatch.setattr(store_module, "atomic_write", held)

    async def body(process: Process) -> None:
        saving = asyncio.ensure_future(process.post(["SCAN", "save"], {"design": "c"}))
        await held.wait_entered()
        disabling = asyncio.ensure_future(process.post(["SCAN", "disable"]))
        await other_block_answers(process, 5, held)
        assert not disabling.done()  # it waits for the write to end
        held.release()
        await disabling
        with pytest.raises(AbortedError):
            await saving
        assert process.get(["SCAN", "state", "value"]) == "Disabled"
        assert process.get(["SCAN", "design", "value"]) == "c"
        controller = process.get_controller("SCAN")
        assert "c" in controller.store.names()

    run(body)

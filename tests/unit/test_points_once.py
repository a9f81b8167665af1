"""A configure computes its scan's points once (issue 8): not again to check
the argument, not again for the children a manager validates and configures
with the same generator, and not again by configure() after validate() of
the same scan."""

from __future__ import annotations

import asyncio
from typing import Any

import pytest

import malcolm.scan.load
from malcolm.demo import demo_generator, demo_process


@pytest.fixture
def computed(monkeypatch: pytest.MonkeyPatch) -> list[Any]:
    """The generators whose scans are built (their points computed) from now
    on: ``scan_points`` builds one it has not kept from data."""
    seen: list[Any] = []
    real = malcolm.scan.load.points_from_data

    def counting(generator: Any) -> Any:
        seen.append(generator)
        return real(generator)

    monkeypatch.setattr(malcolm.scan.load, "points_from_data", counting)
    return seen


def test_configuring_the_demo_scan_computes_its_points_once(computed) -> None:
    async def main() -> None:
        process = demo_process()
        await process.start()
        try:
            generator = demo_generator(5, 6, 0.001)  # no other test's scan
            await process.post(["SCAN", "validate"], {"generator": generator})
            await process.post(["SCAN", "configure"], {"generator": generator})
            for mri in ("SCAN", "DET1", "DET2"):
                assert process.get([mri, "state", "value"]) == "Armed"
                assert process.get([mri, "totalSteps", "value"]) == 30
        finally:
            await process.stop()

    asyncio.run(main())
    assert len(computed) == 1


def test_a_run_computes_its_own_steps_not_the_whole_scan(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The demo parts walk a run a chunk at a time: a 30-million-point scan's
    whole-scan arrays (240 MB each) are never made."""
    from malcolm.scan import gda
    from malcolm.scan.points import ScanPoints

    def refuse(self: ScanPoints, kind: str) -> None:
        raise AssertionError(f"the whole scan's {kind} were computed")

    monkeypatch.setattr(ScanPoints, "_whole", refuse)

    async def main() -> None:
        process = demo_process()
        await process.start()
        try:
            generator = gda.compound(
                gda.line("y", 10_000_000),
                gda.line("x", 3, alternate=True),
                duration=0.001,
            )
            params = {"generator": generator, "axesToMove": ["x"]}
            await process.post(["SCAN", "configure"], params)
            await process.post(["SCAN", "run"])
            assert process.get(["SCAN", "state", "value"]) == "Armed"
            assert process.get(["SCAN", "completedSteps", "value"]) == 3
            assert process.get(["DET1", "framesTaken", "value"]) == 3
            assert process.get(["MOTOR:X", "position", "value"]) == 1.0
        finally:
            await process.stop()

    asyncio.run(main())


def test_points_say_what_they_were_built_from() -> None:
    from malcolm.scan import gda, scan_points

    generator = gda.compound(gda.line("x", 7, 0.0, 1.0), duration=0.125)
    first = scan_points(generator)
    again = scan_points(dict(generator))  # the same content: the same scan
    assert first.content is not None and again.content == first.content
    assert first.copy().content == first.content
    other = scan_points(gda.compound(gda.line("x", 7, 0.0, 1.0), duration=0.25))
    assert other.content != first.content

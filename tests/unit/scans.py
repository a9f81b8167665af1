"""Small scan generators and a process fixture shared by unit tests."""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable
from typing import Any

from malcolm.scan import gda


def compound(*lines: tuple[str, int], duration: float = 0.001) -> dict[str, Any]:
    """A CompoundGenerator of lines (outer first): ("y", 3), ("x", 2)."""
    return gda.compound(
        *(gda.line(axis, size) for axis, size in lines), duration=duration
    )


def run(scenario: Callable[[], Awaitable[Any]], timeout: float = 30) -> Any:
    return asyncio.run(asyncio.wait_for(scenario(), timeout))


def steps(block: Any) -> tuple[int, int, int]:
    return (
        block.configuredSteps.value,
        block.completedSteps.value,
        block.totalSteps.value,
    )

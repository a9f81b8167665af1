"""Parts that record every hook call of a live controller, and the log they write.

A :class:`RecorderPart` hooks every phase of a model. Each call appends a
``start`` event (part, phase, the controller's state, whether the hook got
the block's own device or validate()'s) and, when the hook returns, raises
or is cancelled, an ``end`` event. The live rig adds ``move`` events (from
a subscription to ``state``), ``call`` markers (before each call it makes),
``progress`` (a part's report) and ``completed`` (``completedSteps``), so
that :mod:`malcolm.conformance.checks` can read one ordered log.

Recorders can be told to fail, hang or stall (wait for an event) the next
time they run a phase, and to lag: yield to the loop a number of times
before returning, so that parts of one phase finish in different orders.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from malcolm.fsm import Model, Phase
from malcolm.parts.base import Part, PartRegistrar

#: how long a hung hook waits (only a phase timeout or a cancel ends it)
HANG = 3600.0


@dataclass(frozen=True)
class Event:
    """One entry of the log.

    ``kind`` is ``call`` (``value``: the call or put, ``trigger``: the trigger
    it fires, if known; None once it was refused), ``return`` (the call
    ``value`` returned or raised), ``start``/``end`` (a hook of ``part`` for ``phase``;
    ``state`` where it started, ``own`` False for validate()'s device;
    ``value`` of an end: ``ok``, ``error`` or ``cancelled``), ``move``
    (``state`` -> ``dest``), ``progress`` (``part`` reported ``value`` steps)
    ``completed`` (``completedSteps`` became ``value``) or ``misbehave``
    (``part`` was told to ``fail`` or ``hang`` in ``phase``).
    """

    kind: str
    part: str = ""
    phase: str = ""
    state: str = ""
    dest: str = ""
    value: Any = None
    trigger: str | None = None
    own: bool = True


class RecorderPart(Part):
    """Hooks every phase of a model (see :func:`recorder_class`) and logs it.

    ``lag``: times a hook yields to the loop before it returns.
    ``stepping``: the phase in which it does the run's steps, reporting
    progress after each (``step_lag`` yields between reports).
    """

    def __init__(
        self,
        name: str,
        log: list[Event],
        lag: int = 0,
        stepping: str | None = None,
        step_lag: int = 0,
    ) -> None:
        super().__init__(name)
        self.log = log
        self.lag = lag
        self.stepping = stepping
        self.step_lag = step_lag
        self.controller: Any = None
        self.fail_next: set[str] = set()
        self.hang_next: set[str] = set()
        #: phase -> event the hook waits for (the next time it runs the phase)
        self.stall: dict[str, asyncio.Event] = {}
        #: set when a hook starts waiting for its stall event
        self.stalled = asyncio.Event()
        #: (phase, "fail" | "hang") for each scripted misbehaviour that happened
        self.fired: list[tuple[str, str]] = []

    def setup(self, registrar: PartRegistrar) -> None:
        self.controller = registrar.controller

    async def behave(self, phase: str, task: Any, device: Any) -> None:
        own = device is self.controller.device
        state = self.controller.current
        self.log.append(Event("start", self.name, phase, state, own=own))
        outcome = "error"
        try:
            await self._act(phase, task, device)
            outcome = "ok"
        except asyncio.CancelledError:
            outcome = "cancelled"
            raise
        finally:
            self.log.append(Event("end", self.name, phase, value=outcome, own=own))

    async def _act(self, phase: str, task: Any, device: Any) -> None:
        if phase in self.fail_next:
            self.fail_next.discard(phase)
            self.fired.append((phase, "fail"))
            self.log.append(Event("misbehave", self.name, phase, value="fail"))
            raise RuntimeError(f"injected failure in {phase}")
        if phase in self.hang_next:
            self.hang_next.discard(phase)
            self.fired.append((phase, "hang"))
            self.log.append(Event("misbehave", self.name, phase, value="hang"))
            await asyncio.sleep(HANG)
        event = self.stall.pop(phase, None)
        if event is not None:
            self.stalled.set()
            await event.wait()
        if phase == self.stepping:
            await self._steps(task, device)
        for _ in range(self.lag):
            await asyncio.sleep(0)

    async def _steps(self, task: Any, device: Any) -> None:
        for step in range(device.completedSteps, device.configuredSteps):
            for _ in range(self.step_lag):
                await asyncio.sleep(0)
            self.log.append(Event("progress", self.name, value=step + 1))
            task.report_progress(step + 1)


def _hook(phase: str) -> Callable[..., Any]:
    async def hook(self: RecorderPart, task: Any, device: Any) -> None:
        await self.behave(phase, task, device)

    hook.__name__ = f"on_{phase}"
    return hook


def recorder_class(model: Model) -> type[RecorderPart]:
    """A RecorderPart subclass with a hook for every phase of ``model``."""
    namespace = {
        f"on_{name}": Phase(name, description, model.name)(_hook(name))
        for name, description in model.phases.items()
    }
    return type(f"Recorder{model.name}", (RecorderPart,), namespace)

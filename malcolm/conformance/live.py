"""A live controller built for a model, with recorder parts, on its own loop.

:class:`LiveBlock` builds the model's ``controller:`` class with three
:class:`~malcolm.conformance.recorder.RecorderPart` parts that hook every
phase (lagging 4, 0 and 12 loop turns: the slowest last, so that a phase
runner that returns when the first, or all but the last, of its hooks has
returned is seen), adds it to a Process and logs every move, call,
hook call and progress report in one list, ``log``. Calls go through the
process (``process.post`` / ``process.put``), as any transport's would.
"""

from __future__ import annotations

import asyncio
import shutil
import tempfile
from collections.abc import Coroutine, Sequence
from dataclasses import dataclass
from typing import Any

from malcolm.core import BadValueError, NotAllowedError, Process
from malcolm.fsm import Model, resolve_controller
from malcolm.parts.base import Part

from .recorder import Event, RecorderPart, recorder_class

MRI = "CONFORMANCE"
#: recorder name -> (lag, step_lag)
RECORDERS = {"mid": (4, 1), "fast": (0, 0), "slow": (12, 3)}
#: seconds a call may take before it counts as hung
CALL_TIMEOUT = 10.0


@dataclass
class Outcome:
    """What a call or put did: the state it was made in, its result or error."""

    name: str
    state: str
    result: Any = None
    error: BaseException | None = None

    def __repr__(self) -> str:
        what = f"raised {self.error!r}" if self.error else f"returned {self.result!r}"
        return f"{self.name} in {self.state} {what}"


def run_phases(model: Model) -> tuple[str, ...]:
    """The phases of the run: those of ``done`` out of the running state."""
    if not model.has_state_role("running"):
        return ()
    running = model.state_for("running")
    return tuple(p for t in model.transitions_for("done", running) for p in t.phases)


def controller_for(model: Model) -> type:
    """The model's controller class; ValueError if it names none."""
    cls = resolve_controller(model)
    if cls is None:
        raise ValueError(
            f"{model.path}: model {model.name} names no controller class that"
            " can be imported (controller: module:Class)"
        )
    return cls


class LiveBlock:
    """The model's controller, recorder parts, a Process and one event log."""

    def __init__(
        self,
        model: Model,
        controller: type | None = None,
        phase_timeout: float = CALL_TIMEOUT,
        extra_parts: Sequence[Part] = (),
    ) -> None:
        from malcolm.controllers.manager import ManagerController

        self.model = model
        self.cls = controller or controller_for(model)
        self.loop = asyncio.new_event_loop()
        self.log: list[Event] = []
        phases = run_phases(model)
        stepping = phases[-1] if phases else None
        recorder = recorder_class(model)
        self.recorders: list[RecorderPart] = [
            recorder(name, self.log, lag, stepping, step_lag)
            for name, (lag, step_lag) in RECORDERS.items()
        ]
        kwargs: dict[str, Any] = {
            "model": model,
            "phase_timeout": phase_timeout,
            # long phases (a run) have no default timeout: give them this one
            "phase_timeouts": {p: phase_timeout for p in model.phases_tagged("long")},
        }
        self.tmp = tempfile.mkdtemp(prefix="malcolm-conformance-")
        if issubclass(self.cls, ManagerController):
            kwargs["designs_dir"] = self.tmp
        try:
            self.ctrl = self.cls(MRI, [*self.recorders, *extra_parts], **kwargs)
        except BaseException:
            self.loop.close()
            shutil.rmtree(self.tmp, ignore_errors=True)
            raise
        self.process = Process("conformance")
        self.process.add_controller(self.ctrl)
        self.seen = ""
        self.process.subscribe([MRI, "state", "value"], self._on_state, False)
        if "completedSteps" in self.ctrl.block:
            self.process.subscribe(
                [MRI, "completedSteps", "value"], self._on_completed, False
            )

    # ---- the log
    def _on_state(self, value: str) -> None:
        if self.seen and value != self.seen:
            self.log.append(Event("move", state=self.seen, dest=value))
        self.seen = value

    def _on_completed(self, value: int) -> None:
        self.log.append(Event("completed", value=value))

    def mark(self, name: str, trigger: str | None) -> None:
        self.log.append(Event("call", value=name, trigger=trigger))

    # ---- running things on the loop
    def run(self, coro: Coroutine[Any, Any, Any], timeout: float = CALL_TIMEOUT) -> Any:
        async def bounded() -> Any:
            try:
                return await asyncio.wait_for(coro, timeout)
            except TimeoutError:
                raise AssertionError(
                    f"{self.model.path}: hung for {timeout} s in state {self.state}"
                ) from None

        return self.loop.run_until_complete(bounded())

    @property
    def path(self) -> list[str]:
        """Every state the block has been in, in order (moves from the log)."""
        return [self.model.initial] + [e.dest for e in self.log if e.kind == "move"]

    @property
    def state(self) -> str:
        return str(self.ctrl.current)

    @property
    def health(self) -> str:
        return str(self.ctrl.health.value)

    def trigger_of(self, name: str, put: bool) -> str | None:
        """The trigger a call or put fires, if the model says."""
        if put:
            rule = self.model.attributes.get(name)
            return rule.trigger if rule is not None else None
        return name if name in self.model.triggers() else None

    async def invoke(self, name: str, params: Any = None, put: bool = False) -> Outcome:
        """Make a call (``params``: its arguments) or a put (``params``: the value)."""
        out = Outcome(name, self.state)
        at = len(self.log)
        self.mark(name, self.trigger_of(name, put))
        try:
            if put:
                await self.process.put([MRI, name], params)
            else:
                out.result = await self.process.post([MRI, name], params or {})
        except Exception as e:
            out.error = e
            if isinstance(e, NotAllowedError | BadValueError):
                # refused: it fired nothing, so no move is its doing
                self.log[at] = Event("call", value=name, trigger=None)
        finally:
            self.log.append(Event("return", value=name))
        return out

    # ---- what scenarios use
    def start(self) -> None:
        self.mark("start", "init")
        self.run(self.process.start())

    def call(self, name: str, **params: Any) -> Outcome:
        return self.run(self.invoke(name, params))

    def put(self, name: str, value: Any) -> Outcome:
        return self.run(self.invoke(name, value, put=True))

    def begin(self, name: str, **params: Any) -> asyncio.Task[Outcome]:
        """Start a call without waiting for it."""
        return self.loop.create_task(self.invoke(name, params))

    def stall(self, phase: str) -> asyncio.Event:
        """The slowest recorder waits in ``phase`` (next time) until the
        returned event is set."""
        slowest = self.recorders[-1]
        event = asyncio.Event()
        slowest.stalled = asyncio.Event()
        slowest.stall[phase] = event
        return event

    def wait_stalled(self) -> None:
        self.run(self.recorders[-1].stalled.wait())

    def finish(self, task: asyncio.Task[Outcome]) -> Outcome:
        return self.run(asyncio.wait_for(asyncio.shield(task), CALL_TIMEOUT))

    def close(self) -> None:
        loop = self.loop
        try:
            loop.run_until_complete(asyncio.wait_for(self.process.stop(), 5))
        finally:
            tasks = asyncio.all_tasks(loop)
            for task in tasks:
                task.cancel()
            if tasks:
                loop.run_until_complete(asyncio.gather(*tasks, return_exceptions=True))
            loop.run_until_complete(loop.shutdown_asyncgens())
            loop.close()
            shutil.rmtree(self.tmp, ignore_errors=True)

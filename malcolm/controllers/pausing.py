"""Pause, seek and resume of a runnable block's scan.

A mixin of :class:`~malcolm.controllers.runnable.RunnableController`.
``pause(lastGoodStep)`` (alias ``completedSteps``) goes back to a step (see
:func:`.scan_steps.pause_step`): from the running state the run in progress
is cancelled and waits, Paused, for ``resume()``; elsewhere the block lands
Armed. A put of ``completedSteps`` seeks to that step. Both run beside a
paused run() as a task of their own, so that abort and disable can cancel
them.
"""

from __future__ import annotations

import asyncio
from typing import TYPE_CHECKING, Any

from malcolm.core import (
    AbortedError,
    Attribute,
    BadValueError,
    MapMeta,
    MethodMeta,
    NotAllowedError,
    NumberMeta,
)

from .scan_steps import pause_step

if TYPE_CHECKING:
    from malcolm.fsm import Transition


class PauseAndSeek:
    """``pause()``, ``resume()`` and puts of ``completedSteps``."""

    if TYPE_CHECKING:  # from the rest of RunnableController
        mri: str
        current: str
        completed: Attribute
        configured: Attribute
        total: Attribute
        _paused: bool
        _run_inner: asyncio.Task[Any] | None
        _resume: asyncio.Future[bool] | None
        _seek_op: asyncio.Task[Any] | None
        _claim: object | None
        _claim_name: str
        _op_name: str

        def role(self, state: str | None = None) -> str | None: ...
        def is_busy(self) -> bool: ...
        def busy_with(self) -> str | None: ...
        def choose(self, trigger: str) -> Transition: ...
        async def fire(self, trigger: str, before_move: Any = None) -> Transition: ...
        async def settle(self) -> None: ...
        async def go_fault(self, error: BaseException | str) -> None: ...
        def stop_tasks(self) -> None: ...
        def outcome(self, op: asyncio.Future[Any], name: str) -> Any: ...
        def next_configured(self, completed: int) -> int: ...

    async def do_pause(
        self, lastGoodStep: int | None = None, completedSteps: int | None = None
    ) -> None:
        """Go back to a step; from Running land Paused, otherwise Armed."""
        requested = lastGoodStep if lastGoodStep is not None else completedSteps
        self._check_not_seeking("pause")
        if self._claim is not None:
            raise NotAllowedError(
                f"{self.mri}: cannot pause while {self._claim_name} is in progress"
                f" (state {self.current})"
            )
        running = self.role() == "running"
        if self.role() == "armed" and self.busy_with() == "run":
            # between run() being called and the block running
            raise NotAllowedError(
                f"{self.mri}: cannot pause a run that is not running yet"
                f" (state {self.current})"
            )
        lands_paused = running or self.role() == "paused"
        steps = pause_step(
            requested,
            self.completed.value,
            self.configured.value,
            self.total.value,
            lands_paused,
        )
        try:
            if running:
                inner = self._run_inner
                if inner is None or inner.done():
                    raise NotAllowedError(
                        f"{self.mri}: cannot pause a run that is not running yet"
                        f" (state {self.current})"
                    )
                self._paused = True
                self.choose("pause")
                inner.cancel()
                await asyncio.wait({inner})
                # what the cancelled run phase subscribed to goes with it
                self.stop_tasks()
            await self._seek("pause", steps)
        except (NotAllowedError, BadValueError, AbortedError):
            raise
        except Exception as e:
            if self.is_busy():
                await self.go_fault(e)
            raise

    def method_meta_pause(self) -> MethodMeta:
        step = "Last good step; the scan goes back to it (negative: the current step)"
        return MethodMeta(
            MapMeta(
                {
                    "lastGoodStep": NumberMeta("int32", step, writeable=True),
                    "completedSteps": NumberMeta("int32", step, writeable=True),
                }
            ),
            description="Pause: go back to lastGoodStep (alias completedSteps)",
        )

    async def put_completedSteps(self, steps: int) -> None:  # noqa: N802
        if not 0 <= steps <= self.total.value:
            raise BadValueError(
                f"{self.mri}.completedSteps: {steps} is outside [0, {self.total.value}]"
            )
        try:
            await self._seek("seek", steps)
        except (NotAllowedError, AbortedError):
            raise
        except Exception as e:
            if self.is_busy():
                await self.go_fault(e)
            raise

    async def _seek(self, trigger: str, steps: int) -> None:
        self.choose(trigger)  # fail early if not allowed here
        self._check_not_seeking(trigger)
        # beside a run only once it runs (or waits Paused); never beside an
        # abort or disable taking over, nor any other operation
        beside_run = self._op_name == "run" and self.role() in ("running", "paused")
        busy = self.busy_with()
        if busy is not None and not (busy == "run" and beside_run):
            raise NotAllowedError(
                f"{self.mri}: cannot {trigger} while {busy} is in progress"
                f" (state {self.current})"
            )

        async def seek() -> None:
            async def go_back() -> None:
                # the target is known before the seek chooses where to go next
                self.completed.set_value(steps)
                self.configured.set_value(self.next_configured(steps))

            await self.fire(trigger, before_move=go_back)  # Pause first, if any
            await self.settle()

        # a task of its own, so that abort and disable can cancel it
        self._seek_op = op = asyncio.ensure_future(seek())
        await asyncio.wait({op})
        self.outcome(op, trigger)

    def _check_not_seeking(self, name: str) -> None:
        if self._seek_op is not None and not self._seek_op.done():
            raise NotAllowedError(
                f"{self.mri}: cannot {name} while a pause or seek is in progress"
                f" (state {self.current})"
            )

    def side_operations(self) -> list[asyncio.Future[Any]]:
        return [f for f in (self._seek_op, self._run_inner) if f is not None]

    async def do_resume(self) -> None:
        """Continue a paused scan."""
        self._check_not_seeking("resume")
        resume = self._resume
        if resume is None or resume.done():
            raise NotAllowedError(
                f"{self.mri}: no paused run() is waiting to resume"
                f" (state {self.current})"
            )
        self._paused = False
        try:
            await self.fire("resume")  # the phases the model puts on resume
        except BaseException:
            self._paused = True
            raise
        resume.set_result(True)

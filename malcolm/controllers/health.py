"""Health and faults: what ``health`` shows, and how a block goes to Fault.

A mixin of :class:`~malcolm.controllers.base.Controller`. ``health`` shows a
fault's reason first (until reset), then the problems parts report
(``part: message``), else ``OK``. Going to Fault stops the parts' tasks,
cancels whatever is in progress (its caller gets the reason), runs the
phases the model declares on the ``fault`` transition from here, and moves.
"""

from __future__ import annotations

import asyncio
import logging
from typing import TYPE_CHECKING, Any

from malcolm.core import Alarm, Attribute, MalcolmError, NotAllowedError
from malcolm.fsm import Model, Transition
from malcolm.hooks import Task

log = logging.getLogger(__name__)


def describe(error: BaseException) -> str:
    """An error as ``health`` and callers show it."""
    if isinstance(error, MalcolmError):
        return str(error)
    return f"{type(error).__name__}: {error}"


class Health:
    """Fault reason, parts' problems, and the move to Fault."""

    mri: str
    health: Attribute
    tasks: dict[str, Task]
    _part_problems: dict[str, str]
    _fault_message: str | None
    _faulting: bool
    _background: set[asyncio.Future[Any]]

    if TYPE_CHECKING:  # from the other parts of Controller
        model: Model
        current: str

        def choose(self, trigger: str) -> Transition: ...
        def move(self, t: Transition) -> None: ...
        def on_transition(self, t: Transition) -> None: ...
        async def run_phase(self, phase: str) -> dict[str, Any]: ...
        def cancel_now(self, reason: str | None = None) -> None: ...

    def _init_health(self) -> None:
        self._part_problems = {}
        self._fault_message = None
        self._faulting = False
        self._background = set()

    @property
    def fault_message(self) -> str | None:
        """The reason of the current fault, or None."""
        return self._fault_message

    async def go_fault(self, error: BaseException | str) -> None:
        """Go to Fault with ``error`` as the reason (see the module's text)."""
        message = error if isinstance(error, str) else describe(error)
        t = self._enter_fault(message)
        if t is not None:
            await self._take_fault(t)

    def fault_now(self, message: str) -> None:
        """Go to Fault from synchronous code (a subscription callback): the
        move happens now, or once the fault transition's phases have run."""
        t = self._enter_fault(message)
        if t is None:
            return
        if not t.phases:
            try:
                self.move(t)
            finally:
                self._faulting = False
            return
        fut = asyncio.ensure_future(self._take_fault(t))
        self._background.add(fut)
        fut.add_done_callback(self._background.discard)

    def _enter_fault(self, message: str) -> Transition | None:
        """The synchronous half of a fault; the transition to take, if any."""
        in_fault = self.model.is_state(self.current, "fault")
        if self._faulting or (in_fault and self._fault_message is not None):
            return None  # already (going) in Fault: the first reason stays
        log.warning("%s: fault: %s", self.mri, message)
        for task in self.tasks.values():
            task.stop()
        self._fault_message = message
        self.health.set_value(message, alarm=Alarm.major(message))
        self.cancel_now(message)
        try:
            t = self.choose("fault")
        except NotAllowedError:
            return None  # no fault move from here (Disabled): health says why
        self._faulting = True  # until the move: a second fault waits its turn
        return t

    async def _take_fault(self, t: Transition) -> None:
        try:
            self.on_transition(t)
            for phase in t.phases:
                try:
                    await self.run_phase(phase)
                except Exception as e:  # the block goes to Fault all the same
                    log.warning("%s: %s while going to Fault", self.mri, describe(e))
                    reason = f"{self._fault_message}; then {describe(e)}"
                    self._fault_message = reason
                    self.health.set_value(reason, alarm=Alarm.major(reason))
            if self.current == t.source:
                self.move(t)
        finally:
            self._faulting = False

    def set_health_ok(self) -> None:
        """Forget the fault's reason; health shows the parts' problems, or OK."""
        self._fault_message = None
        self._show_health()

    def set_part_health(self, part: str, message: str | None) -> None:
        """A part reports a problem (``message``) or that it is over (None).

        ``health`` shows a fault's reason first, then the parts' problems
        (``part: message``, joined by ``; ``), else ``OK``. Reporting a
        problem does not change the state: the part decides whether it is a
        fault.
        """
        if message is None:
            self._part_problems.pop(part, None)
        else:
            self._part_problems[part] = str(message)
        self._show_health()

    def _show_health(self) -> None:
        if self._fault_message is not None:
            return  # a fault's reason stays until reset
        if self._part_problems:
            text = "; ".join(f"{p}: {m}" for p, m in self._part_problems.items())
            if text != self.health.value:
                self.health.set_value(text, alarm=Alarm.minor(text))
        elif self.health.value != "OK" or self.health.alarm != Alarm.ok:
            self.health.set_value("OK", alarm=Alarm.ok)

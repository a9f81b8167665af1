"""The model interpreter: choose a transition, run its phases, move.

A mixin of :class:`~malcolm.controllers.base.Controller`. It knows no state
or phase names: everything it needs is in the model (busy states, the
transitions and their phases, guards named after controller methods, the
``long`` phase tag) and subclasses react to moves through the roles of the
states involved (:meth:`Interpreter.on_transition`,
:meth:`Interpreter.on_moved`).
"""

from __future__ import annotations

from collections.abc import Awaitable, Callable
from typing import TYPE_CHECKING, Any

from malcolm.core import Attribute, Method, NotAllowedError
from malcolm.fsm import Model, Transition
from malcolm.hooks import Hook, Task, runner

from .device import Device
from .writers import WRITER

if TYPE_CHECKING:
    from malcolm.core import Block

#: the tag of phases the default phase timeout does not limit (a scan's run)
LONG = "long"


class Interpreter:
    """Runs a model: ``fire(trigger)`` = choose, run the phases, move."""

    # set by Controller.__init__
    mri: str
    model: Model
    block: Block
    state: Attribute
    device: Device
    hooks: dict[str, list[Hook]]
    tasks: dict[str, Task]
    inactive: set[str]
    phase_timeout: float | None
    phase_timeouts: dict[str, float]
    state_listeners: list[Callable[[str, str], None]]
    _state: str

    @property
    def current(self) -> str:
        """The state the block is in."""
        return self._state

    def role(self, state: str | None = None) -> str | None:
        """The role of ``state`` (default: the current one)."""
        return self.model.states[self._state if state is None else state].role

    def is_busy(self) -> bool:
        """Whether the block is in a busy state (work in progress)."""
        return self.model.states[self._state].busy

    def choose(self, trigger: str) -> Transition:
        """The first transition for ``trigger`` from here whose guards pass.

        Guards are controller methods named in the model; each is asked at
        most once per choice.
        """
        state = self._state
        answers: dict[str, bool] = {}

        def guard(name: str) -> bool:
            if name not in answers:
                answers[name] = bool(getattr(self, name)())
            return answers[name]

        for t in self.model.transitions_for(trigger, state):
            if not t.guards and not t.unless:
                return t
            if all(guard(g) for g in t.guards) and not any(guard(g) for g in t.unless):
                return t
        raise NotAllowedError(f"{self.mri}: cannot {trigger} in state {state}")

    async def fire(
        self,
        trigger: str,
        before_move: Callable[[], Awaitable[None]] | None = None,
    ) -> Transition:
        """Choose the transition for ``trigger``, run its phases in order
        (still in the source state), await ``before_move()`` if given, then
        move to the transition's destination.

        The guards are asked once, when the transition is chosen: the move
        goes to that destination even if the phases changed what they look
        at. If a phase raises, nothing moves and the error propagates.
        """
        t = self.choose(trigger)
        self.on_transition(t)
        for phase in t.phases:
            await self.run_phase(phase)
        if before_move is not None:
            await before_move()
        self.move(t)
        return t

    def move(self, t: Transition) -> None:
        """Move along ``t`` (its phases have run): state, writeable flags,
        :meth:`on_moved`, then the state listeners."""
        before = self._state
        if before != t.source:
            raise RuntimeError(f"{self.mri}: cannot move along {t} from {before}")
        self._state = t.dest
        self.state.set_value(t.dest)
        self._update_writeable(before)
        self.on_moved(t)
        for listener in list(self.state_listeners):
            listener(before, t.dest)

    async def settle(self) -> None:
        """Leave busy states by firing ``done`` until the block rests."""
        while self.model.states[self._state].busy:
            await self.fire("done")

    async def _transition_and_settle(self, trigger: str) -> None:
        await self.fire(trigger)
        await self.settle()

    def on_transition(self, t: Transition) -> None:
        """Called when ``t`` is chosen, before its phases (subclasses)."""

    def on_moved(self, t: Transition) -> None:
        """Called after the block moved along ``t`` (subclasses)."""

    # ---- phases
    def timeout_of(self, phase: str) -> float | None:
        """The phase's own timeout, else the default unless the phase is long."""
        if phase in self.phase_timeouts:
            return self.phase_timeouts[phase]
        if LONG in self.model.phase_info[phase].tags:
            return None
        return self.phase_timeout

    def hooks_of(self, phase: str) -> list[Hook]:
        """The hooks that run in ``phase`` (not those of inactive parts)."""
        hooks = self.hooks.get(phase, ())
        if not self.inactive:
            return list(hooks)
        return [h for h in hooks if h.part not in self.inactive]

    async def run_phase(
        self, phase: str, device: Device | None = None
    ) -> dict[str, Any]:
        """Run ``phase``'s hooks concurrently; hooks get ``device`` (by default
        the block's own). Returns what each part returned."""
        device = device or self.device
        return await self.run_hooks(phase, self.hooks_of(phase), device)

    async def run_hooks(
        self, phase: str, hooks: list[Hook], device: Device
    ) -> dict[str, Any]:
        if not hooks:
            device.part_info[phase] = {}
            return {}
        # the hooks (and the tasks and threads they start) inherit this
        # context: their puts carry this block's mri (see writers.py); set
        # and reset in place (writing_as's, without a context manager)
        token = WRITER.set(self.mri)
        try:
            results = await runner.run_phase(
                phase, hooks, self.tasks, device, self.timeout_of(phase)
            )
        finally:
            WRITER.reset(token)
        device.part_info[phase] = results
        return results

    # ---- which calls and puts are allowed now
    def _update_writeable(self, before: str | None = None) -> None:
        """Set the writeable flags of the model's calls and puts for the
        current state (only those whose rule differs from ``before``'s, if
        given), in one delta."""
        state = self._state
        if before is None:
            fields = self._fields_of(
                [(n, self._allowed(n, state)) for n in self._restricted()]
            )
        else:
            fields = self._fields_between(before, state)
        notes: list[list[Any]] = []
        for fld, allowed in fields:
            if fld.meta.writeable != allowed:
                fld.meta.writeable = allowed
                notes.append([[fld.name, "meta", "writeable"], allowed])
        if notes:  # one delta for the move, not one per field
            self.block.notify(notes)

    def _restricted(self) -> list[str]:
        return [*self.model.methods, *self.model.attributes]

    def _allowed(self, name: str, state: str) -> bool:
        """Whether call or put ``name`` is allowed in ``state``."""
        if name in self.model.methods:
            return self.model.allows(name, state)
        return self.model.put_allowed(name, state)

    def _fields_of(self, rules: list[tuple[str, bool]]) -> list[tuple[Any, bool]]:
        """The block's fields the ``(name, allowed)`` rules are about."""
        block = self.block
        methods = self.model.methods
        found = []
        for name, allowed in rules:
            if name in block:
                fld = block[name]
                if isinstance(fld, Method) == (name in methods):
                    found.append((fld, allowed))
        return found

    def _fields_between(self, before: str, after: str) -> list[tuple[Any, bool]]:
        """(field, allowed in ``after``) for each call or put whose rule
        differs between the two states; worked out once per pair and kept
        while the block's fields stay the same ones."""
        cache: dict[tuple[str, str], tuple[int, list[tuple[Any, bool]]]]
        cache = self.__dict__.setdefault("_writeable_fields", {})
        block = self.block
        count = len(block.meta.fields)
        kept = cache.get((before, after))
        if kept is not None and kept[0] == count:
            if all(fld.block is block for fld, _ in kept[1]):
                return kept[1]
        rules = [
            (n, self._allowed(n, after))
            for n in self._restricted()
            if self._allowed(n, before) != self._allowed(n, after)
        ]
        fields = self._fields_of(rules)
        cache[(before, after)] = (count, fields)
        return fields

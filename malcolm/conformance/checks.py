"""Checks on a recorder log (see :mod:`malcolm.conformance.recorder`).

- :func:`observed_moves` / :func:`phase_problems`: each move ran exactly the
  phases of its transition, in order, while the block was in the source
  state (the model's phases, or a reference table's);
- :func:`hook_problems`: every hook of a phase finished before the next
  phase started and before the block moved, and none was cancelled unless
  a part failed, hung or a call interrupted it;
- :func:`progress_problems`: during a run, ``completedSteps`` never passed
  a part that was still doing its steps (progress is the slowest part's).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

from malcolm.fsm import Model, Transition

from .recorder import Event

#: the phases a transition should run (default: the model's)
Expected = Callable[[Transition], tuple[str, ...]]


@dataclass(frozen=True)
class ObservedMove:
    """A move seen in the log, the transition it is taken to be, and the
    phases the block ran in its source state before it."""

    index: int
    source: str
    dest: str
    transition: Transition | None
    ran: tuple[str, ...]  # phase runs since the previous move
    since_call: tuple[str, ...] | None  # phase runs since its call's marker
    #: a part failed, or a call of another trigger came, since the last move
    interrupted: bool


def _where(t: Transition) -> str:
    return f"{t.file}:{t.line}" if t.line else t.file


def observed_moves(log: Sequence[Event], model: Model) -> list[ObservedMove]:
    """Every move in ``log``, with the phases run before it (own device).

    A phase run counts only if every hook of it returned: a run cut short
    (a part failed, or a call cancelled it) is no transition's phases.
    """
    moves: list[ObservedMove] = []
    runs: list[str] = []  # phase runs since the last move
    spoiled: set[int] = set()  # runs a hook of which raised or was cancelled
    run_of: dict[str, int] = {}  # part -> the run its open hook is in
    markers: list[tuple[str | None, int]] = []  # (trigger, len(runs) then)
    in_run: set[str] = set()  # parts that started the latest run
    failed = False

    def good(first: int = 0) -> tuple[str, ...]:
        return tuple(p for k, p in enumerate(runs) if k >= first and k not in spoiled)

    for i, e in enumerate(log):
        if e.kind == "call":
            markers.append((e.trigger, len(runs)))
        elif e.kind == "misbehave":
            failed = True
        elif e.kind == "start" and e.own:
            if not runs or runs[-1] != e.phase or e.part in in_run:
                runs.append(e.phase)
                in_run = set()
            in_run.add(e.part)
            run_of[e.part] = len(runs) - 1
        elif e.kind == "end" and e.own:
            k = run_of.pop(e.part, None)
            if e.value != "ok" and k is not None:
                spoiled.add(k)
                failed = failed or e.value == "error"
        elif e.kind == "move":
            t = _attribute(model, e.state, e.dest, markers, list(good()))
            since = None
            if t is not None:
                at = [n for trig, n in markers if trig == t.trigger]
                if at:
                    since = good(at[-1])
            interrupted = failed or any(
                trig is not None and (t is None or trig != t.trigger)
                for trig, _ in markers
            )
            moves.append(
                ObservedMove(i, e.state, e.dest, t, good(), since, interrupted)
            )
            runs, spoiled, markers, in_run, failed = [], set(), [], set(), False
            run_of.clear()
    return moves


def _attribute(
    model: Model,
    source: str,
    dest: str,
    markers: list[tuple[str | None, int]],
    ran: list[str],
) -> Transition | None:
    """The transition a move most likely took: the one of the latest call's
    trigger, else ``done`` out of a busy state, else the one whose phases
    end the phases run, else the first."""
    options = [t for t in model.transitions if (t.source, t.dest) == (source, dest)]
    if len(options) <= 1:
        return options[0] if options else None
    for trigger, _ in reversed(markers):
        found = [t for t in options if t.trigger == trigger]
        if found:
            return found[0]
    if model.states[source].busy:
        found = [t for t in options if t.trigger == "done"]
        if found:
            return found[0]
    for t in options:
        if not t.phases or tuple(ran[len(ran) - len(t.phases) :]) == t.phases:
            return t
    return options[0]


def phase_problems(
    log: Sequence[Event], model: Model, expected: Expected | None = None
) -> list[str]:
    """Moves that did not run their transition's phases, in order.

    A move made by the call that preceded it, or by ``done``, must have run
    exactly the expected phases; a move that interrupted something (abort,
    pause of a run, a failure) must have run them last.
    """
    want = expected or (lambda t: tuple(t.phases))
    problems = []
    for move in observed_moves(log, model):
        t = move.transition
        if t is None:
            problems.append(
                f"moved {move.source} -> {move.dest}: no transition of model"
                f" {model.name} ({model.path}) makes that move"
            )
            continue
        phases = want(t)
        if move.since_call is not None:
            got, exact = move.since_call, True
        elif not move.interrupted:
            got, exact = move.ran, True
        else:
            got, exact = move.ran, False
        ok = got == phases if exact else got[len(got) - len(phases) :] == phases
        if not ok:
            how = "" if exact else " last"
            problems.append(
                f"transition {t} ({_where(t)}) should run{how} {_list(phases)},"
                f" but the block ran {_list(got)} in {t.source} before it moved"
            )
    return problems


def _list(phases: Sequence[str]) -> str:
    return "[" + ", ".join(phases) + "]"


def hook_problems(log: Sequence[Event], resting: bool = True) -> list[str]:
    """Hooks still running when the next phase started or the block moved,
    hooks started twice, hooks cancelled for no reason, and (``resting``)
    hooks that never finished.

    A cancelled hook is excused by a failure or hang in its phase run, or by
    a call in progress while it ran (``call`` .. ``return`` in the log).
    """
    problems: list[str] = []
    open_hooks: dict[str, tuple[str, int]] = {}  # part -> (phase, start index)
    calls: list[list[int]] = []  # [marker index, return index (or -1)]
    pending: dict[str, list[list[int]]] = {}  # call name -> unreturned spans
    failure = -1  # index of the latest failure or hang
    run_start, run_phase, in_run = -1, "", set()
    for i, e in enumerate(log):
        if e.kind == "call":
            span = [i, -1]
            calls.append(span)
            pending.setdefault(str(e.value), []).append(span)
        elif e.kind == "return" and pending.get(str(e.value)):
            pending[str(e.value)].pop(0)[1] = i
        elif e.kind == "misbehave" or (e.kind == "end" and e.value == "error"):
            failure = i
        if not e.own:
            continue
        if e.kind == "start":
            if e.phase != run_phase or e.part in in_run:
                run_start, run_phase, in_run = i, e.phase, set()
            in_run.add(e.part)
            for part, (phase, _) in open_hooks.items():
                if phase != e.phase:
                    problems.append(
                        f"phase {e.phase} started while part {part!r} was still"
                        f" running its {phase} hook: a phase must end only when"
                        " all its hooks have returned"
                    )
            if open_hooks.get(e.part, ("", 0))[0] == e.phase:
                problems.append(
                    f"part {e.part!r} started its {e.phase} hook again before the"
                    " previous one had returned"
                )
            open_hooks[e.part] = (e.phase, i)
        elif e.kind == "end":
            started = open_hooks.pop(e.part, (e.phase, i))[1]
            overlapping = any(c < i and (r == -1 or r > started) for c, r in calls)
            if e.value == "cancelled" and failure < run_start and not overlapping:
                problems.append(
                    f"part {e.part!r}'s {e.phase} hook was cancelled though no part"
                    " failed or hung and no call interrupted it"
                )
        elif e.kind == "move":
            for part, (phase, _) in open_hooks.items():
                problems.append(
                    f"moved {e.state} -> {e.dest} while part {part!r} was still"
                    f" running its {phase} hook"
                )
    if resting:
        for part, (phase, _) in open_hooks.items():
            problems.append(f"part {part!r}'s {phase} hook never returned")
    return list(dict.fromkeys(problems))


def progress_problems(
    log: Sequence[Event], model: Model, run_phases: Sequence[str]
) -> list[str]:
    """``completedSteps`` during a run must not pass a part still working in
    the run's phases: the scan's progress is the slowest working part's."""
    if not model.has_state_role("running"):
        return []
    running = model.state_for("running")
    problems = []
    state = model.initial
    completed = 0
    reported: dict[str, int] = {}
    working: dict[str, str] = {}  # part -> phase
    for e in log:
        if e.kind == "move":
            state = e.dest
            if state == running:
                reported = {}
        elif e.kind == "completed":
            if state == running:
                behind = {p: reported.get(p, completed) for p in working}
                slowest = min(behind.values(), default=None)
                if slowest is not None and e.value > slowest:
                    part = min(behind, key=lambda p: behind[p])
                    problems.append(
                        f"completedSteps became {e.value} while part {part!r} was"
                        f" still working at step {slowest}: progress must be the"
                        " slowest working part's"
                    )
            completed = e.value
        elif e.kind == "progress":
            reported[e.part] = e.value
        elif e.kind == "start" and e.own and e.phase in run_phases:
            working[e.part] = e.phase
            reported.setdefault(e.part, completed)
        elif e.kind == "end" and e.own and working.get(e.part) == e.phase:
            del working[e.part]
    return list(dict.fromkeys(problems))

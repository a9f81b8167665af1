"""The design rules every model must follow, beyond being well formed."""

from __future__ import annotations

import importlib
from collections import deque

from .errors import ModelError, Problem
from .model import Model

FAULT = "Fault"
DISABLING = "Disabling"
DISABLED = "Disabled"
ABORTING = "Aborting"
DONE = "done"


def check_model(model: Model, guard_provider: type | None = None) -> list[Problem]:
    """Every breach of the design rules, each naming the file:line and the
    state, phase or guard at fault. An empty list means the model conforms.

    Guards are checked only when ``guard_provider`` is given: each must be a
    callable attribute of it (see :func:`resolve_controller`).
    """
    problems: list[Problem] = []
    problems += _unreachable(model)
    problems += _no_fault_or_disable(model)
    problems += _busy_cannot_abort(model)
    problems += _busy_not_left_by_done(model)
    problems += _unused_phases(model)
    problems += _calls_without_transitions(model)
    if guard_provider is not None:
        problems += _missing_guards(model, guard_provider)
    return problems


def resolve_controller(model: Model) -> type | None:
    """The class named by the model's ``controller``, or None when the model
    names none or its module does not exist (yet).

    Raises :class:`ModelError` when the module exists but fails to import or
    lacks the class.
    """
    if model.controller is None:
        return None
    module_name, _, class_name = model.controller.partition(":")
    file, line = model.where("controller")
    try:
        module = importlib.import_module(module_name)
    except Exception as e:  # anything a broken module raises
        missing = getattr(e, "name", None)
        if isinstance(e, ModuleNotFoundError) and missing is not None:
            if module_name == missing or module_name.startswith(missing + "."):
                return None  # not written yet
        problem = Problem(file, line, f"cannot import {module_name}: {e}")
        raise ModelError([problem]) from e
    cls = getattr(module, class_name, None)
    if not isinstance(cls, type):
        raise ModelError(
            [Problem(file, line, f"{module_name} has no class {class_name}")]
        )
    return cls


def _state_problem(model: Model, state: str, message: str) -> Problem:
    file, line = model.where("state", state)
    return Problem(file, line, message)


def _unreachable(model: Model) -> list[Problem]:
    moves = model.moves()
    seen = {model.initial}
    todo = deque([model.initial])
    while todo:
        for dest in moves.get(todo.popleft(), ()):
            if dest not in seen:
                seen.add(dest)
                todo.append(dest)
    return [
        _state_problem(
            model,
            name,
            f"state {name} is unreachable from initial state {model.initial}",
        )
        for name in model.states
        if name not in seen
    ]


def _no_fault_or_disable(model: Model) -> list[Problem]:
    problems = []
    for required in (FAULT, DISABLING):
        if required not in model.states:
            problems.append(Problem(str(model.path), None, f"no {required} state"))
    moves = model.moves()
    for name in model.states:
        if name == DISABLED:
            continue
        for required in (FAULT, DISABLING):
            if required == name or required not in model.states:
                continue
            if required not in moves[name]:
                problems.append(
                    _state_problem(
                        model, name, f"state {name} has no move to {required}"
                    )
                )
    return problems


def _abort_target(model: Model, state: str) -> str:
    """Aborting if the model that first declared ``state`` has an Aborting
    state, else Disabling: states inherited from a model without Aborting
    (Resetting, Saving, Loading) are abandoned by disabling."""
    origin = model
    while origin.parent is not None and state in origin.parent.states:
        origin = origin.parent
    return ABORTING if ABORTING in origin.states else DISABLING


def _busy_cannot_abort(model: Model) -> list[Problem]:
    problems = []
    moves = model.moves()
    for name in sorted(model.busy_states()):
        if name in (ABORTING, DISABLING):
            continue  # these are the aborts themselves
        target = _abort_target(model, name)
        if target not in moves[name]:
            problems.append(
                _state_problem(
                    model, name, f"busy state {name} cannot abort: no move to {target}"
                )
            )
    return problems


def _busy_not_left_by_done(model: Model) -> list[Problem]:
    problems = []
    for name in sorted(model.busy_states()):
        done = model.transitions_for(DONE, name)
        if not done:
            problems.append(
                _state_problem(
                    model, name, f"busy state {name} has no '{DONE}' transition"
                )
            )
        elif done[-1].guards or done[-1].unless:
            last = done[-1]
            problems.append(
                Problem(
                    last.file,
                    last.line,
                    f"busy state {name}: the last '{DONE}' transition ({last}) is "
                    f"guarded, so '{DONE}' may leave {name} nowhere",
                )
            )
    return problems


def _unused_phases(model: Model) -> list[Problem]:
    used = {p for t in model.transitions for p in t.phases}
    problems = []
    for name in model.phases:
        if name not in used:
            file, line = model.where("phase", name)
            problems.append(Problem(file, line, f"phase {name} is on no transition"))
    return problems


def _calls_without_transitions(model: Model) -> list[Problem]:
    triggers = model.triggers()
    problems = []
    for name, allowed in model.methods.items():
        if name not in triggers:
            continue
        file, line = model.where("method", name)
        for state in sorted(allowed):
            if not model.transitions_for(name, state):
                problems.append(
                    Problem(
                        file,
                        line,
                        f"method {name} is allowed in {state} but no {name} "
                        f"transition leaves {state}",
                    )
                )
    for name, rule in model.attributes.items():
        if rule.trigger is None:
            continue
        file, line = model.where("attribute", name)
        if rule.trigger not in triggers:
            problems.append(
                Problem(
                    file,
                    line,
                    f"attribute {name}: trigger {rule.trigger} is on no transition",
                )
            )
            continue
        for state in sorted(rule.allowed):
            if not model.transitions_for(rule.trigger, state):
                problems.append(
                    Problem(
                        file,
                        line,
                        f"attribute {name} may be put in {state} but no "
                        f"{rule.trigger} transition leaves {state}",
                    )
                )
    return problems


def _missing_guards(model: Model, provider: type) -> list[Problem]:
    problems = []
    provider_name = getattr(provider, "__name__", repr(provider))
    for t in model.transitions:
        for guard in dict.fromkeys((*t.guards, *t.unless)):
            if not callable(getattr(provider, guard, None)):
                problems.append(
                    Problem(
                        t.file,
                        t.line,
                        f"guard {guard} on transition {t} is not provided by "
                        f"{provider_name}",
                    )
                )
    return problems

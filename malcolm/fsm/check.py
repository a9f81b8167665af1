"""The design rules every model must follow, beyond being well formed.

Rules look states up by **role** (``fault``, ``disabling``, ``disabled``,
``aborting``), never by name, so a model may name its states as it likes;
a model that lacks a role a rule needs gets a problem saying so.
"""

from __future__ import annotations

import importlib
from collections import deque

from .errors import ModelError, Problem
from .model import Model, Transition

DONE = "done"

#: Triggers a controller fires by itself: ``init`` once at process start,
#: ``done`` to leave a busy state, ``fault`` when something fails. A
#: controller class may name more in a ``fires`` class attribute.
CONTROLLER_TRIGGERS = frozenset({"init", DONE, "fault"})

#: role -> what the rules need it for (in messages)
_ROLE_USES = {
    "fault": "every state must be able to move to Fault (rule 2)",
    "disabling": "every state must be able to move to Disabling, and busy "
    "states without Aborting abort through it (rules 2 and 3)",
    "disabled": "the state exempt from rule 2 is the disabled one",
}


def check_model(model: Model, guard_provider: type | None = None) -> list[Problem]:
    """Every breach of the design rules, each naming the file:line and the
    state, phase, transition or guard at fault. An empty list means the
    model conforms.

    ``guard_provider`` is the controller class (see :func:`resolve_controller`):
    with it, every guard must be a callable attribute of it, and a transition
    that runs phases counts as fired by a call only if the class implements
    the call (``do_<trigger>``; checked when the class has ``add_call``, as
    controllers do).
    """
    problems: list[Problem] = []
    problems += _missing_roles(model)
    problems += _unreachable(model)
    problems += _no_fault_or_disable(model)
    problems += _busy_cannot_abort(model)
    problems += _busy_not_left_by_done(model)
    problems += _unused_phases(model)
    problems += _calls_without_transitions(model)
    problems += _shadowed_transitions(model)
    problems += _phases_fired_by_nothing(model, guard_provider)
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


def _role(model: Model, role: str) -> str | None:
    """The state with ``role``, or None."""
    return model.state_for(role) if model.has_state_role(role) else None


def _missing_roles(model: Model) -> list[Problem]:
    return [
        Problem(
            str(model.path),
            None,
            f"model {model.name} has no state with role {role!r}: {why}",
        )
        for role, why in _ROLE_USES.items()
        if not model.has_state_role(role)
    ]


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
    required = [s for s in (_role(model, "fault"), _role(model, "disabling")) if s]
    disabled = _role(model, "disabled")
    moves = model.moves()
    for name in model.states:
        if name == disabled:
            continue
        for target in required:
            if target != name and target not in moves[name]:
                problems.append(
                    _state_problem(model, name, f"state {name} has no move to {target}")
                )
    return problems


def _abort_target(model: Model, state: str) -> str | None:
    """The aborting state if the model that first declared ``state`` has
    one, else the disabling state: states inherited from a model without
    aborting (Resetting, Saving, Loading) are abandoned by disabling."""
    origin = model
    while origin.parent is not None and state in origin.parent.states:
        origin = origin.parent
    if origin.has_state_role("aborting"):
        return model.state_for("aborting")
    return _role(model, "disabling")


def _busy_cannot_abort(model: Model) -> list[Problem]:
    problems = []
    moves = model.moves()
    exempt = {_role(model, "aborting"), _role(model, "disabling")}
    for name in sorted(model.busy_states()):
        if name in exempt:
            continue  # these are the aborts themselves
        target = _abort_target(model, name)
        if target is not None and target not in moves[name]:
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


def _shadowed_transitions(model: Model) -> list[Problem]:
    """A transition after an unguarded one with the same trigger and source
    is never taken: the first wins."""
    problems = []
    for t in model.transitions:
        earlier = model.transitions_for(t.trigger, t.source)
        winner = next((e for e in earlier if not (e.guards or e.unless)), None)
        if (
            winner is not None
            and winner is not t
            and earlier.index(t) > earlier.index(winner)
        ):
            where = f" (line {winner.line})" if winner.line else ""
            problems.append(
                Problem(
                    t.file,
                    t.line,
                    f"transition {t}{_runs(t)} is never taken: the unguarded "
                    f"{winner}{where} comes first",
                )
            )
    return problems


def _runs(t: Transition) -> str:
    return f" (phases {', '.join(t.phases)})" if t.phases else ""


def _firers(
    model: Model, trigger: str, source: str, provider: type | None
) -> list[str]:
    """What fires ``trigger`` in ``source``: the controller, a call, a put."""
    found = []
    extra = frozenset(getattr(provider, "fires", ()) or ())
    if trigger in CONTROLLER_TRIGGERS | extra:
        found.append("the controller")
    allowed = model.methods.get(trigger)
    implements = provider is None or not callable(getattr(provider, "add_call", None))
    if not implements:
        implements = callable(getattr(provider, f"do_{trigger}", None))
    if allowed is not None and source in allowed and implements:
        found.append(f"call {trigger}()")
    for name, rule in model.attributes.items():
        if rule.trigger == trigger and source in rule.allowed:
            found.append(f"a put of {name}")
    return found


def _phases_fired_by_nothing(model: Model, provider: type | None) -> list[Problem]:
    """A transition that runs phases must be fired by something, or its
    phases never run (transitions without phases may exist only to allow a
    move, as interop.md's move table asks)."""
    problems = []
    for t in model.transitions:
        if not t.phases or _firers(model, t.trigger, t.source, provider):
            continue
        why = [f"'{t.trigger}' is not a trigger the controller fires"]
        allowed = model.methods.get(t.trigger)
        if allowed is None:
            why.append(f"no method {t.trigger} is listed under methods")
        elif t.source not in allowed:
            why.append(f"method {t.trigger} is not allowed in {t.source}")
        elif provider is not None:
            name = getattr(provider, "__name__", repr(provider))
            why.append(f"{name} does not implement {t.trigger}() (do_{t.trigger})")
        why.append(f"no attribute put fires {t.trigger} in {t.source}")
        problems.append(
            Problem(
                t.file,
                t.line,
                f"transition {t} runs phases {', '.join(t.phases)} but nothing "
                f"fires it: {'; '.join(why)}",
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

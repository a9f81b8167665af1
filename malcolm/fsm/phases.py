"""Phase decorators: ``@RunnableDevice.Configure`` marks a part's function as
one to run in that phase. The classes are generated from the models."""

from __future__ import annotations

from typing import Any, TypeVar

from .model import Model

PHASES_ATTR = "__malcolm_phases__"

F = TypeVar("F")


class Phase:
    """A hook point of a model. Calling it on a function registers the
    function for the phase and returns it unchanged.

    Phases are equal when their names are, whichever model they come from.
    """

    __slots__ = ("name", "description", "model")

    def __init__(self, name: str, description: str, model: str) -> None:
        self.name = name
        self.description = description
        self.model = model

    def __call__(self, fn: F) -> F:
        target: Any = fn
        if isinstance(fn, staticmethod | classmethod):
            target = fn.__func__
        if not callable(target):
            raise TypeError(
                f"@{self.model}.{self.name} decorates functions, not {fn!r}"
            )
        phases = getattr(target, PHASES_ATTR, ())
        if self.name not in phases:
            setattr(target, PHASES_ATTR, (*phases, self.name))
        return fn

    def __eq__(self, other: object) -> bool:
        if isinstance(other, Phase):
            return self.name == other.name
        return NotImplemented

    def __hash__(self) -> int:
        return hash(self.name)

    def __repr__(self) -> str:
        return f"<Phase {self.model}.{self.name}>"


def phases_of(fn: object) -> tuple[str, ...]:
    """The names of the phases ``fn`` was registered for, in decoration order
    (innermost decorator first)."""
    if isinstance(fn, staticmethod | classmethod):
        fn = fn.__func__
    return tuple(getattr(fn, PHASES_ATTR, ()))


class PhaseNamespace(type):
    """Metaclass of the generated classes: a missing phase is an error that
    names the model and lists the phases it has."""

    model: Model

    def __getattr__(cls, name: str) -> Any:
        if name.startswith("__"):
            raise AttributeError(name)
        model = cls.__dict__.get("model")
        phases = ", ".join(model.phases) if model else ""
        raise AttributeError(
            f"{cls.__name__} has no phase {name!r}; its phases are: {phases}"
        )

    def __iter__(cls) -> Any:
        return iter([getattr(cls, name) for name in cls.model.phases])


def model_class(model: Model) -> type:
    """A class named after the model whose attributes are its phases, plus
    ``model``, the :class:`Model` itself."""
    namespace: dict[str, Any] = {
        name: Phase(name, description, model.name)
        for name, description in model.phases.items()
    }
    namespace["model"] = model
    namespace["__doc__"] = model.description or f"Phases of the {model.name} model."
    namespace["__module__"] = __name__.rsplit(".", 1)[0]
    return PhaseNamespace(model.name, (), namespace)

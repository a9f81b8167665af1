"""Hypothesis state machines that drive a live controller built for a model
(needs the test extras: hypothesis).

:func:`machine_for` picks the machine for the model's controller class (a
runnable device's, a manager's, or the common one) and binds it to the
model; :func:`run_machine` runs it as a test::

    from malcolm.conformance.machines import run_machine
    from malcolm.fsm import load_model

    def test_my_model():
        run_machine(load_model("my/models/scanner.yaml"), examples=30)
"""

from __future__ import annotations

from hypothesis import HealthCheck, settings
from hypothesis.stateful import run_state_machine_as_test

from malcolm.fsm import Model

from ..checks import Expected
from ..live import controller_for
from .base import ControllerMachine
from .manager import ManagerMachine
from .runnable import RunnableMachine

__all__ = ["ControllerMachine", "machine_for", "run_machine"]


def machine_for(model: Model, expected: Expected | None = None) -> type:
    """The machine class for ``model``'s controller class, bound to ``model``."""
    from malcolm.controllers.manager import ManagerController
    from malcolm.controllers.runnable import RunnableController

    cls = controller_for(model)
    if issubclass(cls, RunnableController):
        base: type = RunnableMachine
    elif issubclass(cls, ManagerController):
        base = ManagerMachine
    else:
        base = ControllerMachine
    return type(
        f"{base.__name__}For{model.name}",
        (base,),
        {"model": model, "expected": staticmethod(expected) if expected else None},
    )


def run_machine(
    model: Model,
    examples: int = 30,
    steps: int = 40,
    expected: Expected | None = None,
) -> None:
    """Run the machine for ``model``; AssertionError names what went wrong."""
    run_state_machine_as_test(
        machine_for(model, expected),
        settings=settings(
            max_examples=examples,
            stateful_step_count=steps,
            deadline=None,
            suppress_health_check=[HealthCheck.too_slow],
        ),
    )

"""The machine built from every model (builtin, or given with
--malcolm-models) moves only as the model says, over random walks."""

from __future__ import annotations

from pathlib import Path

from hypothesis import given, settings
from hypothesis import strategies as st

from malcolm.conformance.testing import model_or_fail


class _Walker:
    """Stands in for a controller: guards answer from ``answers``."""

    def __init__(self, guards: set[str]) -> None:
        self.answers: dict[str, bool] = {}
        for guard in guards:
            setattr(self, guard, lambda guard=guard: self.answers[guard])


@settings(max_examples=60, deadline=None)
@given(data=st.data())
def test_random_walk_follows_the_model(model_path: Path, data: st.DataObject) -> None:
    model = model_or_fail(model_path)
    walker = _Walker(model.guards())
    model.build_machine(walker)
    moves = model.moves()
    state = model.initial
    assert walker.state == state
    for _ in range(data.draw(st.integers(0, 60), label="steps")):
        triggers = sorted(model.triggers_from(state))
        if not triggers:
            break
        trigger = data.draw(st.sampled_from(triggers), label="trigger")
        walker.answers = {
            g: data.draw(st.booleans(), label=g) for g in sorted(model.guards())
        }
        expected = next(
            (
                t
                for t in model.transitions_for(trigger, state)
                if all(walker.answers[g] for g in t.guards)
                and not any(walker.answers[g] for g in t.unless)
            ),
            None,
        )
        moved = getattr(walker, trigger)()
        if expected is None:
            assert not moved
            assert walker.state == state
        else:
            assert moved
            assert walker.state == expected.dest
            assert expected.dest in moves[state]
        state = walker.state
        assert state in model.states


@settings(max_examples=30, deadline=None)
@given(data=st.data())
def test_done_always_leaves_a_busy_state(model_path: Path, data: st.DataObject) -> None:
    model = model_or_fail(model_path)
    for state in sorted(model.busy_states()):
        walker = _Walker(model.guards())
        walker.answers = {
            g: data.draw(st.booleans(), label=g) for g in sorted(model.guards())
        }
        model.build_machine(walker, initial=state)
        assert walker.done(), f"done did not leave busy state {state}"

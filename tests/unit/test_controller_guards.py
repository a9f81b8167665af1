"""Guards are asked once per move: the phases of the chosen transition run,
and the block goes where that transition goes, even if the phases change
what the guards look at."""

import asyncio
import textwrap

from malcolm.controllers.base import Controller
from malcolm.core import Process
from malcolm.fsm import load_model, model_class
from malcolm.parts import Part

MODEL = """\
name: Fork
extends: stateful
states:
  Working: {busy: true, description: Parts work}
  Left: {description: Went left}
  Right: {description: Went right}
phases:
  GoLeft: Parts go left
  GoRight: Parts go right
transitions:
  - {trigger: work, source: Ready, dest: Working}
  - {trigger: done, source: Working, dest: Left, guards: [flag], phases: [GoLeft]}
  - {trigger: done, source: Working, dest: Right, phases: [GoRight]}
methods:
  work: [Ready]
"""


def test_the_move_goes_where_the_chosen_transition_goes(tmp_path):
    path = tmp_path / "fork.yaml"
    path.write_text(textwrap.dedent(MODEL))
    model = load_model(path)
    Fork = model_class(model)

    class ForkController(Controller):
        flag_value = False

        def flag(self) -> bool:
            return self.flag_value

        async def do_work(self) -> None:
            await self.operation("work", self._transition_and_settle("work"))

    ran = []

    class Flipper(Part):
        @Fork.GoRight
        async def right(self, task, device):
            ran.append("GoRight")
            controller.flag_value = True  # would now choose Left

        @Fork.GoLeft
        async def left(self, task, device):
            ran.append("GoLeft")

    controller = ForkController("FORK", [Flipper("flip")], model=model)

    async def scenario():
        process = Process()
        process.add_controller(controller)
        await process.start()
        await process.post(["FORK", "work"])
        return controller.block.state.value

    assert asyncio.run(scenario()) == "Right"
    assert ran == ["GoRight"]

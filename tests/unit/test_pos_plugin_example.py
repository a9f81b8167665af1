"""The design document's PosPluginPart example, run against a soft position plugin.

The class body below is the document's text unchanged (its imports work
as written: malcolm.sm is an alias of malcolm.fsm); only ``_generate_xml``
is filled in by a subclass, as the document leaves it a placeholder.
"""

import asyncio

from malcolm.controllers.runnable import RunnableController
from malcolm.controllers.stateful import StatefulController
from malcolm.core import ChildControllerPart, Controls, Process
from malcolm.modules.ADCore import PositionPlugin
from malcolm.sim.position_plugin import SoftPositionPluginPart
from malcolm.sm import AreaDetectorRunnableDevice

# fmt: off
# ---- verbatim from block-hierarchy.rst -------------------------------------


@Controls(PositionPlugin)
class PosPluginPart(ChildControllerPart):

    def _generate_xml(self, start, num):
        # Generate some XML to be sent down to the PositionPlugin that
        # represents the next num positions after start
        return "<xml_goes_here/>"

    @AreaDetectorRunnableDevice.Configure
    def configure(self, task, device):
        pos = self.child
        # start some puts off in the background
        futures = task.put_async({
            pos.delete: True,
            pos.idStart: 1,
            pos.enableCallbacks: True})
        # calculate the first 100 positions
        xml = self._generate_xml(0, 100)
        # wait until puts are done
        task.wait_all(futures)
        # put the first 100 points
        task.put(pos.xml, xml)
        self._loaded = 100

    def _load_pos(self, positions, device):
        pos = self.child
        if positions < 100 and self._loaded < device.totalSteps:
            # add up to 100 more positions
            num = min(100, device.totalSteps - self._loaded)
            xml = self._generate_xml(self._loaded, num)
            pos.xml.put(xml)
            self._loaded += num

    @AreaDetectorRunnableDevice.PreRunPluginStart
    def start_plugin(self, task, device):
        pos = self.child
        # Each time the number of positions left changes, call a function
        # to load positions if we're getting low
        # This will live until we unsubscribe from the self.load_id
        self.load_id = task.subscribe(pos.positions, self._load_pos, device)
        # Start us off running
        running_f = task.when_matches(pos.running, True)
        self.done_f = task.put_async(pos.start, True)
        task.wait_all(running_f)

    @AreaDetectorRunnableDevice.Running
    def running(self, task, device):
        task.wait_all(self.done_f)
        task.unsubscribe(self.load_id)

# ---- end of the document's text ---------------------------------------------
# fmt: on


class XmlPosPluginPart(PosPluginPart):
    def _generate_xml(self, start, num):
        rows = "".join(f'<position x="{i}"/>' for i in range(start, start + num))
        return f"<pos_layout><positions>{rows}</positions></pos_layout>"


def line(size: int) -> dict:
    return {
        "typeid": "scanpointgenerator:generator/CompoundGenerator:1.0",
        "generators": [
            {
                "typeid": "scanpointgenerator:generator/LineGenerator:1.0",
                "axes": ["x"],
                "units": ["mm"],
                "start": [0],
                "stop": [1],
                "size": size,
                "alternate": False,
            }
        ],
        "excluders": [],
        "mutators": [],
        "duration": 0.001,
    }


def test_pos_plugin_part_runs_a_scan_through_the_soft_plugin():
    async def scenario():
        process = Process()
        plugin = SoftPositionPluginPart("plugin")
        process.add_controller(StatefulController("SIM:POS", [plugin]))
        part = XmlPosPluginPart("pos", "SIM:POS")
        det = RunnableController(
            "SIM:DET", [part], model="area_detector_runnable_device"
        )
        process.add_controller(det)
        await process.start()
        pos = process.get_block("SIM:POS")

        await process.post(["SIM:DET", "configure"], {"generator": line(250)})
        # Configure did the three puts and loaded the first 100 positions
        assert pos.delete.value is True
        assert pos.enableCallbacks.value is True
        assert pos.positions.value == 100
        assert det.block.state.value == "Armed"

        await process.post(["SIM:DET", "run"])
        assert det.block.state.value == "Finished"
        assert det.block.completedSteps.value == 250
        # every frame got a position: 100 + 100 + 50 loaded in three puts
        assert pos.processed.value == 250
        assert plugin.xml_puts == 3
        assert pos.running.value is False
        # Running unsubscribed, so loading stopped with the scan
        assert not process._subs.get("SIM:POS")

    asyncio.run(asyncio.wait_for(scenario(), 30))


def test_verbatim_class_declares_what_it_controls_and_its_phases():
    from malcolm.fsm import phases_of

    assert PosPluginPart.controls is PositionPlugin
    assert phases_of(PosPluginPart.configure) == ("Configure",)
    assert phases_of(PosPluginPart.start_plugin) == ("PreRunPluginStart",)
    assert phases_of(PosPluginPart.running) == ("Running",)
    assert PosPluginPart("p", "X")._generate_xml(0, 100) == "<xml_goes_here/>"

"""The co-ordination layer's own configure cost, without hardware.

    .venv/bin/python -m benchmarks.coordination [--repeats N]

The BeamlineManager definition (``beamline.BeamlineManager``) over three
in-memory device managers that keep the device contract (configure takes
``fileDir`` and ``formatName``, a ``datasets`` table, a Validate hook that
reads the scan's points) but touch no hardware, beside the same three
devices configured at once with no BeamlineManager (what its Configure
phase asks of them). Everything runs on one loop and costs CPU only, so
the difference is what the co-ordination layer itself adds to a configure:
the beamline's controller and phases, its Validate (each child's
``validate()``), planning the scan, the calls between the layers, and the
scan file's ``datasets``. Each configure is of a scan not configured
before (1e-6 s more per point each time, as GDA sends one per scan);
each is followed by a reset, not timed. The figures are process CPU per
configure (median), alternating the two cases so both see the machine's
load of the moment. The ratio is the co-ordination layer's own cost (1.0:
it adds nothing); issue 13's target, the three layers within 3x the demo's
single layer, is `benchmarks.beamline`'s, with the hardware.
"""

from __future__ import annotations

import argparse
import asyncio
import tempfile
import time
from collections.abc import Awaitable, Callable
from typing import Any

from benchmarks.table import Row, median, render
from malcolm.beamline import add_beamline_manager
from malcolm.core import NumberMeta, Process, StringMeta
from malcolm.fsm import RunnableDevice
from malcolm.parts import Part, PartRegistrar
from malcolm.parts.datasets import datasets_meta
from malcolm.scan import gda

DEVICES = {"DET": "primary", "MOTORS": "position_value", "ZEBRA": "monitor"}
SOURCE = (
    "CPU per configure, median; issue 13's target (the 3 layers within 3x the"
    " demo's single layer) is benchmarks.beamline's"
)
#: the ratio is the co-ordination layer's own cost, not issue 13's ratio
RATIO_NOTE = "beamline / devices alone"


class MemoryDevicePart(Part):
    """A device manager's configure contract in memory: its arguments, a
    datasets table naming its raw file, a Validate that reads the scan."""

    def __init__(self, name: str, kind: str) -> None:
        super().__init__(name)
        self.kind = kind

    def setup(self, registrar: PartRegistrar) -> None:
        registrar.add_configure_arg("fileDir", StringMeta("dir"), "")
        registrar.add_configure_arg("formatName", StringMeta("name"), self.name)
        if self.kind == "primary":
            registrar.add_configure_arg("frameTimeout", NumberMeta("float64"), 0.0)
        if self.kind == "position_value":
            registrar.controller.block.simultaneousAxes.set_value(["x", "y"])
        self.datasets = registrar.add_attribute("datasets", datasets_meta())

    @RunnableDevice.Validate
    async def validate(self, task: Any, device: Any) -> dict[str, Any]:
        device.points.position(device.points.axes[0], 0)  # reads the scan
        return {}

    @RunnableDevice.Configure
    async def configure(self, task: Any, device: Any) -> None:
        name = device.params["formatName"]
        self.datasets.set_value(
            {"name": [f"{name}.data"], "filename": [f"{name}.h5"],
             "type": [self.kind], "rank": [0], "path": ["/data"],
             "uniqueid": ["/uid"]}
        )  # fmt: skip


async def make_process() -> Process:
    process = Process()
    add_beamline_manager(
        process,
        {mri: [MemoryDevicePart(mri.lower(), kind)] for mri, kind in DEVICES.items()},
    )
    await process.start()
    return process


def grid(duration: float) -> dict[str, Any]:
    return gda.compound(
        gda.line("y", 10, 0.0, 0.09),
        gda.line("x", 10, 0.0, 0.09, alternate=True),
        duration=duration,
    )


def spiral(duration: float) -> dict[str, Any]:
    # rings 0.01 apart, about 10,000 points
    return gda.compound(gda.spiral("x", "y", 0.564, scale=0.01), duration=duration)


async def cpu_of(work: Callable[[], Awaitable[Any]]) -> float:
    start = time.process_time()
    await work()
    return time.process_time() - start


async def measure(repeats: int) -> list[Row]:
    process = await make_process()
    rows = []
    with tempfile.TemporaryDirectory() as file_dir:
        args = {"axesToMove": ["x", "y"], "fileDir": file_dir}

        async def beamline(generator: dict[str, Any]) -> float:
            took = await cpu_of(
                lambda: process.post(
                    ["BL", "configure"], {"generator": generator, **args}
                )
            )
            await process.post(["BL", "reset"])
            return took

        async def devices(generator: dict[str, Any]) -> float:
            async def configure(mri: str) -> None:
                await process.post(
                    [f"BL:{mri}", "configure"],
                    {"generator": generator, **args,
                     "formatName": f"bench-{mri.lower()}"},
                )  # fmt: skip

            took = await cpu_of(
                lambda: asyncio.gather(*(configure(mri) for mri in DEVICES))
            )
            await asyncio.gather(*(process.post([f"BL:{m}", "reset"]) for m in DEVICES))
            return took

        step = iter(range(1, 10**9))
        for shape, make in (("10x10 grid", grid), ("10,000-point spiral", spiral)):
            for _ in range(3):  # warm up
                await beamline(make(0.1 + next(step) * 1e-6))
                await devices(make(0.1 + next(step) * 1e-6))
            layers, alone = [], []
            for _ in range(repeats):
                layers.append(await beamline(make(0.1 + next(step) * 1e-6)))
                alone.append(await devices(make(0.1 + next(step) * 1e-6)))
            lay, one = median(layers) * 1e3, median(alone) * 1e3
            rows += [
                Row(f"{shape}: beamline over 3 in-memory devices", lay, "ms", "", "-"),
                Row(f"{shape}: the 3 devices at once, alone", one, "ms", "", "-"),
                Row(f"{shape}: ratio", lay / one, "x", "-", "-", RATIO_NOTE),
            ]
    await process.stop()
    return rows


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.coordination")
    parser.add_argument("--repeats", type=int, default=100)
    args = parser.parse_args(argv)
    print(render(asyncio.run(measure(args.repeats)), SOURCE))


if __name__ == "__main__":
    main()

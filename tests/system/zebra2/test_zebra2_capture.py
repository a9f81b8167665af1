"""PCAP capture into HDF5 from the simulated box (a subprocess).

A scan of N frames writes N rows per captured column, equal to what the
simulator sent to a second data client (the ``pandablocks`` library's own
parser on its own connection), with units, scale and offset.
"""

from __future__ import annotations

import asyncio

import h5py
import numpy as np
import pytest

from malcolm.config.build import build_definition
from malcolm.core import Process
from malcolm.io.zebra2.data import DataClient, EndData, FrameData, StartData
from malcolm.scan import gda

from .conftest import RawClient

MRI = "Z:CAPTURE"
N = 12

SETUP = [
    "CLOCK1.PERIOD.UNITS=ms",
    "CLOCK1.PERIOD=20",
    "CLOCK1.WIDTH.UNITS=ms",
    "CLOCK1.WIDTH=10",
    "CLOCK1.ENABLE=ONE",
    "CLOCK1.WIDTH=10",
    "COUNTER1.ENABLE=ONE",
    "COUNTER1.TRIG=CLOCK1.OUT",
    "COUNTER1.STEP=1",
    "COUNTER2.ENABLE=ONE",
    "COUNTER2.TRIG=CLOCK1.OUT",
    "COUNTER2.STEP=5",
    "COUNTER2.OUT.SCALE=0.5",
    "COUNTER2.OUT.OFFSET=10",
    "COUNTER2.OUT.UNITS=mm",
    "PCAP.ENABLE=ONE",
    "PCAP.GATE=ONE",
    "PCAP.TRIG=CLOCK1.OUT",
]
FIELDS = ["COUNTER1.OUT Value", "COUNTER2.OUT Min Max Mean", "PCAP.TS_TRIG Value"]


async def _watch(sim) -> asyncio.Future[list]:
    """A second data client, connected (the box said ``OK``: it will be sent
    the next experiment), and the task of everything it receives in it."""
    client = DataClient(sim.host, sim.data_port, scaled=True)
    await client.connect()

    async def receive() -> list:
        got = []
        try:
            async for item in client.experiment():
                got.append(item)
        finally:
            await client.close()
        return got

    return asyncio.ensure_future(receive())


def test_a_pcap_scan_of_n_frames_writes_n_rows_per_column(sim, tmp_path):
    path = tmp_path / "data" / "capture.h5"

    async def main():
        process = Process("cap")
        params = {
            "host": sim.host,
            "control_port": sim.control_port,
            "data_port": sim.data_port,
        }
        build_definition("zebra2.Capture", params, MRI, process=process)
        await process.start()
        raw = await RawClient.open(sim)
        try:
            for command in SETUP:
                assert await raw.ask(command) == ["OK"], command
            watcher = await _watch(sim)  # connected before the arm
            generator = gda.compound(gda.line("x", N), duration=0.02)
            await process.post(
                [MRI, "configure"],
                {
                    "generator": generator,
                    "captureFields": FIELDS,
                    "captureFile": str(path),
                },
            )
            await process.post([MRI, "run"])
            block = process.get_block(MRI)
            assert block.state.value == "Finished"
            sent = await asyncio.wait_for(watcher, 10)
            captured = await raw.ask("*PCAP.CAPTURED?")
            return block.samplesWritten.value, block.captureEnd.value, sent, captured
        finally:
            await raw.close()
            await process.stop()

    written, end, sent, captured = asyncio.run(main())
    start = next(x for x in sent if isinstance(x, StartData))
    frames = np.concatenate([x.data for x in sent if isinstance(x, FrameData)])
    ending = next(x for x in sent if isinstance(x, EndData))
    assert written == ending.samples == len(frames) >= N
    assert end.startswith(f"{written} ")
    assert captured == [f"OK ={written}"]
    with h5py.File(path, "r") as f:
        names = sorted(f)
        assert names == sorted(frames.dtype.names)
        for name in names:
            assert f[name].shape == (written,), name
            np.testing.assert_array_equal(f[name][()], frames[name], err_msg=name)
        assert f.attrs["end_samples"] == written
        counts = f["COUNTER1.OUT.Value"][()]
        assert list(np.diff(counts)) == [1.0] * (written - 1)  # every trigger
        mean = f["COUNTER2.OUT.Mean"]
        assert mean.attrs["units"] == "mm"
        assert mean.attrs["scale"] == 0.5 and mean.attrs["offset"] == 10
        heads = {f"{x.name}.{x.capture}" for x in start.fields}
        assert heads == set(names)


@pytest.mark.parametrize("fields", [["NOPE.OUT Value"], ["COUNTER1.OUT Sideways"]])
def test_a_bad_capture_field_refuses_configure_naming_it(sim, tmp_path, fields):
    async def main():
        process = Process("cap")
        params = {"host": sim.host, "control_port": sim.control_port}
        params["data_port"] = sim.data_port
        build_definition("zebra2.Capture", params, MRI, process=process)
        await process.start()
        try:
            with pytest.raises(Exception) as e:
                await process.post(
                    [MRI, "configure"],
                    {
                        "generator": gda.compound(gda.line("x", 2)),
                        "captureFields": fields,
                        "captureFile": str(tmp_path / "x.h5"),
                    },
                )
            return str(e.value), process.get_block(MRI).state.value
        finally:
            await process.stop()

    message, state = asyncio.run(main())
    assert fields[0].split()[0] in message
    assert state == "Fault"


def test_a_scan_in_two_runs_appends_the_second_to_the_file(sim, tmp_path):
    path = tmp_path / "two.h5"

    async def main():
        process = Process("cap")
        params = {
            "host": sim.host,
            "control_port": sim.control_port,
            "data_port": sim.data_port,
        }
        build_definition("zebra2.Capture", params, MRI, process=process)
        await process.start()
        raw = await RawClient.open(sim)
        try:
            for command in SETUP:
                assert await raw.ask(command) == ["OK"], command
            generator = gda.compound(gda.line("x", 10), duration=0.02)
            await process.post(
                [MRI, "configure"],
                {
                    "generator": generator,
                    "breakpoints": [5, 5],
                    "captureFields": FIELDS[:1],
                    "captureFile": str(path),
                },
            )
            block = process.get_block(MRI)
            await process.post([MRI, "run"])
            assert block.state.value == "Armed"
            first = int(block.captureEnd.value.split()[0])
            await process.post([MRI, "run"])
            assert block.state.value == "Finished"
            second = int(block.captureEnd.value.split()[0])
            return first, second, block.samplesWritten.value
        finally:
            await raw.close()
            await process.stop()

    first, second, written = asyncio.run(main())
    assert first >= 5 and second >= 5
    assert written == first + second
    with h5py.File(path, "r") as f:
        counts = f["COUNTER1.OUT.Value"][()]
    assert len(counts) == first + second
    # both runs' samples, in order: the counter only goes up
    assert all(b > a for a, b in zip(counts, counts[1:]))

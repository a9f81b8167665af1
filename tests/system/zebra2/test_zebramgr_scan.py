"""The ZebraManager on the simulated box (a subprocess, over TCP): a line
and a snaking grid give exactly one PCAP row per point, in order, each with
its point's uniqueid, in a file another process can read once run()
returns; ``datasets`` lists the file's datasets as GDA reads them."""

from __future__ import annotations

import asyncio

import numpy as np
import pytest

from malcolm.core import MalcolmError
from malcolm.scan import gda

from .zebramgr import MRI, read_elsewhere, wait_for, zebra_process


def test_a_line_gives_one_row_per_point_with_its_uniqueid(sim, tmp_path):
    n = 25

    async def main():
        process = zebra_process(sim)
        await process.start()
        try:
            block = process.get_block(MRI)
            await process.post(
                [MRI, "configure"],
                {
                    "generator": gda.compound(gda.line("x", n), duration=0.004),
                    "axesToMove": ["x"],
                    "fileDir": str(tmp_path),
                    "formatName": "panda",
                },
            )
            assert block.state.value == "Armed"
            datasets = block.datasets.value
            await process.post([MRI, "run"])
            return block.state.value, block.completedSteps.value, datasets
        finally:
            await process.stop()

    state, completed, datasets = asyncio.run(main())
    assert (state, completed) == ("Finished", n)
    data = read_elsewhere(tmp_path / "panda.h5")
    assert data["uniqueid"] == list(range(1, n + 1))
    # the simulated encoder reads the point's index at each pulse
    assert data["COUNTER1.OUT.Value"] == [float(i) for i in range(n)]
    ts = np.array(data["PCAP.TS_TRIG.Value"])
    assert len(ts) == n and (np.diff(ts) > 0).all()
    np.testing.assert_allclose(np.diff(ts), 0.004, rtol=1e-3)  # the scan's pace
    assert list(datasets["name"]) == ["panda.COUNTER1.OUT", "panda.PCAP.TS_TRIG"]
    assert list(datasets["filename"]) == ["panda.h5"] * 2
    assert list(datasets["type"]) == ["monitor"] * 2
    assert list(datasets["rank"]) == [0, 0]
    assert list(datasets["path"]) == ["/COUNTER1.OUT.Value", "/PCAP.TS_TRIG.Value"]
    assert list(datasets["uniqueid"]) == ["/uniqueid"] * 2


@pytest.mark.parametrize("axes", [["y", "x"], ["x"]])
def test_a_snake_grid_gives_one_row_per_point_in_one_or_many_runs(sim, tmp_path, axes):
    rows, cols = 4, 5
    generator = gda.compound(
        gda.line("y", rows), gda.line("x", cols, alternate=True), duration=0.002
    )

    async def main():
        process = zebra_process(sim)
        await process.start()
        try:
            block = process.get_block(MRI)
            params = {"generator": generator, "axesToMove": axes}
            params["fileDir"] = str(tmp_path)
            await process.post([MRI, "configure"], params)
            runs = []
            while block.state.value == "Armed":
                await process.post([MRI, "run"])
                runs.append(block.completedSteps.value)
            return block.state.value, runs
        finally:
            await process.stop()

    state, runs = asyncio.run(main())
    assert state == "Finished"
    total = rows * cols
    expected_runs = [total] if len(axes) == 2 else list(range(cols, total + 1, cols))
    assert runs == expected_runs
    data = read_elsewhere(tmp_path / "zebra.h5")  # formatName: the mri's name
    assert data["uniqueid"] == list(range(1, total + 1))


def test_no_file_dir_captures_but_writes_no_file(sim, tmp_path):
    async def main():
        process = zebra_process(sim)
        await process.start()
        try:
            block = process.get_block(MRI)
            generator = gda.compound(gda.line("x", 10), duration=0.002)
            await process.post([MRI, "configure"], {"generator": generator})
            await process.post([MRI, "run"])
            return block.state.value, block.completedSteps.value, block.datasets.value
        finally:
            await process.stop()

    state, completed, datasets = asyncio.run(main())
    assert (state, completed) == ("Finished", 10)
    assert list(datasets["name"]) == []
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("name", ["a/b", ".."])
def test_a_bad_format_name_is_refused_naming_it(sim, tmp_path, name):
    async def main():
        process = zebra_process(sim)
        await process.start()
        try:
            generator = gda.compound(gda.line("x", 3), duration=0.01)
            params = {"generator": generator, "fileDir": str(tmp_path)}
            with pytest.raises(MalcolmError) as e:
                await process.post([MRI, "configure"], {**params, "formatName": name})
            return str(e.value), process.get_block(MRI).state.value
        finally:
            await process.stop()

    message, state = asyncio.run(main())
    assert "formatName" in message and repr(name) in message
    assert state == "Ready"


def test_a_file_dir_that_is_a_file_is_refused_naming_it(sim, tmp_path):
    not_dir = tmp_path / "plain"
    not_dir.write_text("x")

    async def main():
        process = zebra_process(sim)
        await process.start()
        try:
            generator = gda.compound(gda.line("x", 3), duration=0.01)
            params = {"generator": generator, "fileDir": str(not_dir)}
            with pytest.raises(MalcolmError) as e:
                await process.post([MRI, "configure"], params)
            return str(e.value), process.get_block(MRI).state.value
        finally:
            await process.stop()

    message, state = asyncio.run(main())
    assert "fileDir" in message and repr(str(not_dir)) in message
    assert state == "Ready"
    assert not_dir.read_text() == "x"


def test_a_10000_point_spiral_gives_10000_rows(sim, tmp_path):
    """At 50 us a point: configure writes no per-point tables (the counter
    and PCOMP are set by a start, a step and a count) and capture keeps
    up."""
    generator = gda.compound(gda.spiral("x", "y", 56.4), duration=50e-6)

    async def main():
        process = zebra_process(sim)
        await process.start()
        try:
            block = process.get_block(MRI)
            params = {"generator": generator, "fileDir": str(tmp_path)}
            await process.post([MRI, "configure"], params)
            total = block.totalSteps.value
            await process.post([MRI, "run"])
            return total, block.state.value
        finally:
            await process.stop()

    total, state = asyncio.run(main())
    assert 9900 < total < 10100 and state == "Finished"
    data = read_elsewhere(tmp_path / "zebra.h5")
    assert data["uniqueid"] == list(range(1, total + 1))
    ts = np.array(data["PCAP.TS_TRIG.Value"])
    np.testing.assert_allclose(np.diff(ts), 50e-6, rtol=1e-3)


def test_the_children_show_what_configure_set_up(sim, tmp_path):
    """The box's blocks are the manager's children (zebra2.Manager): within
    a poll they show the position compare the scan set and its wiring."""

    async def main():
        process = zebra_process(sim, poll_period=0.05)
        await process.start()
        try:
            block = process.get_block(MRI)
            generator = gda.compound(gda.line("x", 33), duration=0.01)
            await process.post([MRI, "configure"], {"generator": generator})
            pcomp = process.get_block(f"{MRI}:PCOMP1")
            await wait_for(pcomp, "PULSES", lambda v: v == 33, timeout=5)
            wiring = await wait_for(
                block, "wiring", lambda v: "PCAP.TRIG" in list(v["sink"]), timeout=5
            )
            sources = dict(zip(wiring["sink"], wiring["source"]))
            return pcomp.INP.value, pcomp.START.value, sources
        finally:
            await process.stop()

    inp, start, sources = asyncio.run(main())
    assert (inp, start) == ("COUNTER1.OUT", 2)
    assert sources["PCAP.TRIG"] == "PCOMP1.OUT"
    assert sources["PCAP.ENABLE"] == "PCOMP1.ACTIVE"
    assert sources["COUNTER1.TRIG"] == "CLOCK1.OUT"

"""Channel.put_and_read on the pyepics backend: the readback's get is sent
from libca's thread the moment the put completes, and gives what the put
left; errors as a put's and a get's, against the simulated IOC."""

from __future__ import annotations

import pytest

from malcolm.io import ChannelError
from malcolm.io.ca.backend import PyepicsBackend

from .conftest import PREFIX, run

CAM = f"{PREFIX}:CAM"


def test_put_and_read_gives_the_readback_the_put_left(ioc):
    async def scenario() -> None:
        backend = PyepicsBackend()
        exposure = backend.channel(
            f"{CAM}:Exposure_RBV", f"{CAM}:Exposure", default=0.0
        )
        mode = backend.channel(
            f"{CAM}:TriggerMode_RBV", f"{CAM}:TriggerMode", default=""
        )
        readback = backend.channel(f"{CAM}:DetectorState_RBV", default="")
        for channel in (exposure, mode, readback):
            await channel.connect(5)
        original = (await exposure.get()).value, (await mode.get()).value
        try:
            for value in (0.125, 0.25, 0.375):
                reading = await exposure.put_and_read(value)
                assert reading.value == value  # the get's, not a monitor's
            assert (await mode.put_and_read("External")).value == "External"
            assert (await mode.put_and_read("Internal")).value == "Internal"
            # refused before anything is sent: the PV keeps its value
            with pytest.raises(ChannelError, match="'Sideways' is not one of"):
                await mode.put_and_read("Sideways")
            assert (await mode.get()).value == "Internal"
            with pytest.raises(ChannelError, match="is a readback"):
                await readback.put_and_read("Idle")
        finally:
            await exposure.put(original[0])
            await mode.put(original[1])
            await backend.close()

    run(scenario())

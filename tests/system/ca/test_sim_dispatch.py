"""The simulated IOC's demand records run their readback's update in place
(malcolm.sim.beamline_ioc.dispatch): a put with completion still completes
with the readback showing the value, as areaDetector's do."""

from __future__ import annotations

from benchmarks import raw_ca
from malcolm.sim.beamline_ioc import SimIOC

from .conftest import PREFIX


def test_a_demand_put_completes_with_its_readback_showing_it(ioc: SimIOC) -> None:
    names = ["Exposure", "Exposure_RBV", "TriggerMode", "TriggerMode_RBV"]
    raw = raw_ca.RawCA([f"{PREFIX}:CAM:{n}" for n in names])
    cam = f"{PREFIX}:CAM"
    original = raw.get(f"{cam}:Exposure"), raw.get(f"{cam}:TriggerMode")
    behind = []
    try:
        for i in range(100):
            exposure = 0.1 + i * 1e-4
            raw.put_all({f"{cam}:Exposure": exposure, f"{cam}:TriggerMode": i % 2})
            shown = raw.get(f"{cam}:Exposure_RBV"), raw.get(f"{cam}:TriggerMode_RBV")
            if abs(shown[0] - exposure) > 1e-9 or shown[1] != i % 2:
                behind.append((i, shown))
    finally:
        raw.put_all({f"{cam}:Exposure": original[0], f"{cam}:TriggerMode": original[1]})
        raw.close()
    assert behind == []

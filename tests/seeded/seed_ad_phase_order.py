"""Seeded defect: the areaDetector starts its driver before its plugins
(PreRunDriverStart before PreRunPluginStart)."""

from tests.seeded import seed_models

seed_models(
    {
        "area_detector_runnable_device.yaml": (
            "Run: [PreRunPluginStart, PreRunDriverStart, Running, PostRun]",
            "Run: [PreRunDriverStart, PreRunPluginStart, Running, PostRun]",
        )
    }
)

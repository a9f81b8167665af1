"""The ZebraManager served over pvAccess (``malcolm serve``), driven as GDA
drives a device: read ``meta``, ``state``, configure's defaults and
``datasets``; configure with a CompoundGenerator structure (a snaking grid)
and ``fileDir``/``formatName``; run; the file has one row per point."""

from __future__ import annotations

from typing import Any

from p4p import Type, Value

from malcolm.io.pva.convert import to_dict

from ..conftest import launch, wait_ready
from .zebramgr import MRI, read_elsewhere

SPG = "scanpointgenerator:generator"
LINE = Type(
    [("axes", "as"), ("units", "as"), ("start", "ad"), ("stop", "ad"),
     ("size", "i"), ("alternate", "?")],
    id=f"{SPG}/LineGenerator:1.0",
)  # fmt: skip
COMPOUND = Type(
    [("generators", "av"), ("excluders", "av"), ("mutators", "av"),
     ("duration", "d"), ("continuous", "?"), ("delay_after", "d")],
    id=f"{SPG}/CompoundGenerator:1.0",
)  # fmt: skip


def line(axis: str, size: int, alternate: bool = False) -> Value:
    """A LineGenerator structure as GDA sends it."""
    return Value(
        LINE,
        {"axes": [axis], "units": ["mm"], "start": [0.0], "stop": [1.0],
         "size": size, "alternate": alternate},
    )  # fmt: skip


def call(ctx: Any, method: str, args: Value | None = None) -> Any:
    request = Value(Type([("method", "s")]), {"method": method})
    return ctx.rpc(MRI, args or Value(Type([]), {}), request=request, timeout=30)


def configure_args(file_dir: str) -> Value:
    args = Type(
        [
            ("generator", COMPOUND.aspy()),
            ("axesToMove", "as"),
            ("fileDir", "s"),
            ("formatName", "s"),
        ],
        id="structure",
    )
    value = Value(
        args, {"axesToMove": ["y", "x"], "fileDir": file_dir, "formatName": "panda"}
    )
    value["generator"] = Value(
        COMPOUND,
        {
            "generators": [line("y", 3), line("x", 4, alternate=True)],
            "excluders": [],
            "mutators": [],
            "duration": 0.005,
            "continuous": True,
            "delay_after": 0.0,
        },
    )
    return value


def test_gda_configures_and_runs_the_zebra_manager_over_pva(sim, tmp_path):
    process_file = tmp_path / "process.yaml"
    process_file.write_text(
        "block.zebra2.ZebraManager:\n"
        f"    mri: {MRI}\n"
        f"    host: {sim.host}\n"
        f"    control_port: {sim.control_port}\n"
        f"    data_port: {sim.data_port}\n"
    )
    served = launch("serve", str(process_file))
    try:
        wait_ready(served, MRI)
        ctx = served.context()
        assert ctx.get(f"{MRI}.state", timeout=5)["value"] == "Ready"
        meta = ctx.get(f"{MRI}.meta", timeout=5)
        assert "configure" in meta["fields"] and "datasets" in meta["fields"]
        configure = ctx.get(f"{MRI}.configure", timeout=5)
        defaults = to_dict(configure["meta.defaults"])
        assert defaults == {"breakpoints": [], "fileDir": "", "formatName": "zebra"}
        call(ctx, "configure", configure_args(str(tmp_path)))
        assert ctx.get(f"{MRI}.state", timeout=5)["value"] == "Armed"
        datasets = to_dict(ctx.get(f"{MRI}.datasets", timeout=5)["value"])
        call(ctx, "run")
        state = ctx.get(f"{MRI}.state", timeout=5)["value"]
        completed = ctx.get(f"{MRI}.completedSteps", timeout=5)["value"]
    finally:
        served.stop()
    assert (state, completed) == ("Finished", 12)
    assert list(datasets["name"]) == ["panda.COUNTER1.OUT", "panda.PCAP.TS_TRIG"]
    assert list(datasets["type"]) == ["monitor", "monitor"]
    assert list(datasets["rank"]) == [0, 0]
    assert list(datasets["uniqueid"]) == ["/uniqueid", "/uniqueid"]
    assert read_elsewhere(tmp_path / "panda.h5")["uniqueid"] == list(range(1, 13))

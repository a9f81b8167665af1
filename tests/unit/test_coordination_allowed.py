"""DeviceChildPart.allowed_now reads the child's method's ``writeable`` as
the child's state changes (straight from the child's block, no copy of the
method and its last call's arguments)."""

from __future__ import annotations

from pathlib import Path

from malcolm.parts.coordination import DeviceChildPart

from .scans import run
from .test_coordination import make, spiral


def test_allowed_now_follows_the_childs_state(tmp_path: Path) -> None:
    async def scenario() -> None:
        p, _ = await make(tmp_path)
        parts = p.get_controller("BL").parts.values()
        det = next(
            x for x in parts if isinstance(x, DeviceChildPart) and x.mri == "BL:DET"
        )
        assert det.allowed_now("configure") and not det.allowed_now("run")
        await p.post(["BL", "configure"], {"generator": spiral(),
                     "axesToMove": ["x", "y"], "fileDir": str(tmp_path)})  # fmt: skip
        assert p.get(["BL:DET", "state", "value"]) == "Armed"
        for method in ("run", "configure", "reset", "abort", "pause"):
            expected = p.get(["BL:DET", method, "meta", "writeable"])
            assert det.allowed_now(method) is expected, method
        assert det.allowed_now("run") and not det.allowed_now("configure")
        # no such method, no such child: not allowed, no error
        assert det.allowed_now("nonesuch") is False
        det.mri = "BL:NONESUCH"
        assert det.allowed_now("run") is False

    run(scenario)

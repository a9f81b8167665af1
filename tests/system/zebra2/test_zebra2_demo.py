"""``malcolm demo --zebra2``: the demo with a simulated box, its manager and
capture block."""

from __future__ import annotations

import asyncio
import io

from malcolm.demo import demo_generator, serve_demo


def test_the_demo_includes_a_simulated_zebra2_when_asked():
    out, err = io.StringIO(), io.StringIO()
    generator = demo_generator(duration=0.001)
    status = asyncio.run(
        serve_demo(True, out=out, err=err, signals=(), generator=generator, zebra2=True)
    )
    text = out.getvalue()
    assert status == 0, err.getvalue()
    assert "malcolm demo: simulated Zebra2 box: control 127.0.0.1:" in text
    blocks = [line.split() for line in text.splitlines() if line.startswith("  ")]
    lines = {words[0]: words[1] for words in blocks if len(words) > 1}
    assert lines["ZEBRA2"] == "Ready"
    assert lines["ZEBRA2:PCOMP1"] == "Ready" and lines["ZEBRA2:CAPTURE"] == "Ready"
    assert "SCAN Finished" in text


def test_the_demo_has_no_zebra2_unless_asked():
    out = io.StringIO()
    generator = demo_generator(duration=0.001)
    asyncio.run(serve_demo(True, out=out, signals=(), generator=generator))
    assert "ZEBRA2" not in out.getvalue()


def test_a_failed_start_lets_go_of_the_pvaccess_port(monkeypatch):
    """The box failing to start (injected) after pvAccess is serving: the
    demo's error reaches the caller and the port is free again."""
    import socket

    import pytest

    from malcolm.parts import zebra2_demo

    async def broken(process):
        raise OSError("no box today")

    monkeypatch.setattr(zebra2_demo, "start_demo_zebra2", broken)
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(OSError, match="no box today"):
        asyncio.run(
            serve_demo(True, out=io.StringIO(), signals=(), pva_port=port, zebra2=True)
        )
    with socket.socket() as s:  # refused while a server still holds it
        s.bind(("127.0.0.1", port))

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

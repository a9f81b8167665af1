"""``benchmarks/zebra2.py`` prints its table (run small here, on 127.0.0.1:
8888/8889 of the isolated namespace; its figures depend on the machine and
are not asserted: the targets are in the table and the report)."""

from __future__ import annotations

import asyncio

from benchmarks import zebra2
from benchmarks.table import HEADER, render


def test_the_zebra2_benchmark_prints_its_table() -> None:
    proc = zebra2.start_sim()
    try:
        rows = asyncio.run(zebra2.main(zebra2.parse(["--quick"])))
    finally:
        zebra2.stop_sim(proc)
    assert all(r.measured > 0 for r in rows)
    lines = render(rows).splitlines()
    assert lines[0].split() == list(HEADER)
    cases = [
        "introspect tier 2 -> 19 ready children",
        "*CHANGES? poll through the manager / bare socket",
        "capture to HDF5: malcolm / pandablocks write_hdf_files",
        "  on one recorded stream, replayed at full speed",
        "largest rate sustained 0.5 s, none lost",
    ]
    assert [line[: len(c)] for line, c in zip(lines[2:], cases)] == cases

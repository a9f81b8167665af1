"""Saves two designs over and over until it is killed.

The child process of ``test_design_atomic_save``; also where both designs are
defined, so that the test compares the file with exactly what was saved.

    python atomic_save_child.py DESIGNS_DIR store|write FIRST

prints ``ready`` once it starts saving, then ``saved 0`` or ``saved 1`` after
each save of design A or B (alternating, starting with FIRST). ``store``
saves through ``DesignStore.save`` (dump then atomic write); ``write`` only
replaces the file with ``atomic_write``, with the texts the parent dumped to
``DESIGNS_DIR/texts/{0,1}.yaml``, so that nearly every kill lands inside a
write.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from malcolm.editor.store import DesignStore, atomic_write
from malcolm.parts.design import (
    ExportPart,
    FixedBool,
    FixedFloat,
    FixedInt,
    FixedString,
    FixedTable,
    FollowerPart,
    ModelPart,
    PalettePart,
)

MRI = "KILL:ME"
NAME = "design"


def design_a() -> list[Any]:
    """Thousands of small records."""
    records: list[Any] = [
        ModelPart("DesignA"),
        PalettePart("PCOMP1", 12, 15, True),
        PalettePart("PCAP", 200, 230, True),
        ExportPart("Start", "PCOMP1.START", "Start of the scan"),
        FollowerPart("PCOMP2.START", "Start"),
    ]
    for i in range(2000):
        records.append(FixedInt(f"A{i}.WIDTH", i * 7 - 1000))
        if i % 5 == 0:
            records.append(FixedBool(f"A{i}.ENABLE", i % 2 == 0))
    return records


def design_b() -> list[Any]:
    """Fewer but bigger records: long strings and a long table."""
    records: list[Any] = [
        ModelPart("DesignB"),
        PalettePart("SEQ1", 0, 0, False),
        ExportPart("Arm", "PCAP.ARM"),
    ]
    for i in range(1000):
        records.append(FixedString(f"B{i}.LABEL", f"label {i} " + "b" * (i % 300)))
        records.append(FixedFloat(f"B{i}.GAIN", i / 8))
    rows = [{"Time1": i, "Time2": -i, "Repeats": i % 17} for i in range(1500)]
    records.append(FixedTable("SEQ1.TABLE", rows))
    return records


def main(designs_dir: Path, mode: str, first: int) -> None:
    store = DesignStore(MRI, designs_dir)
    designs = [design_a(), design_b()] if mode == "store" else []
    texts = [(designs_dir / "texts" / f"{k}.yaml").read_text() for k in (0, 1)]
    path = store.dir / f"{NAME}.yaml"
    print("ready", flush=True)
    i = first
    while True:
        k = i % 2
        if mode == "write":
            atomic_write(path, texts[k])
        else:
            store.save(NAME, designs[k])
        print(f"saved {k}", flush=True)
        i += 1


if __name__ == "__main__":
    main(Path(sys.argv[1]), sys.argv[2], int(sys.argv[3]))

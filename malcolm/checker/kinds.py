"""Tell the kind of a file (model, process, design, definition) by its text.

Only the text is looked at (top-level keys, and the keys under each
``block.*``), so that a file too broken to parse still gets the loader that
will explain what is wrong with it:

- a **model** has top-level ``states:`` or ``transitions:`` (or ``extends``,
  ``initial``, ``phases``);
- a **process** file has ``include``, ``define.*`` sections, ``block.*``
  sections that give an ``mri``, or nothing but ``block.*`` sections (a
  definition has a controller, parts or parameters; ``malcolm serve`` reads
  such a file as a process file, so ``check`` does too);
- a **design** (saved settings) has ``parts.ModelPart``, ``PalettePart``,
  ``ExportPart``, ``FollowerPart`` or ``fixed.*`` sections;
- anything else is a block **definition**.
"""

from __future__ import annotations

import re

__all__ = ["DESIGN_KINDS", "KINDS", "MODEL_KEYS", "detect_kind"]

KINDS = ("definition", "process", "design", "model")

DESIGN_KINDS = frozenset(
    {"parts.ModelPart", "parts.PalettePart", "parts.ExportPart", "parts.FollowerPart"}
)

#: Top-level keys of a state-machine model (a definition's have a dot).
MODEL_KEYS = frozenset({"states", "transitions", "extends", "initial", "phases"})

_TOP_KEY = re.compile(r"""^(?:"([^"\n]*)"|'([^'\n]*)'|([^\s#'"\-?:][^:\n#]*?))\s*:""")
_INDENTED_KEY = re.compile(r"""^[ \t]+(?:-[ \t]+)?["']?([\w.-]+)["']?\s*:""")


def _top_level_keys(text: str) -> list[tuple[str, int]]:
    """``(key, line index)`` of every top-level mapping key, by text alone."""
    keys = []
    for i, line in enumerate(text.splitlines()):
        m = _TOP_KEY.match(line)
        if m:
            keys.append((next(g for g in m.groups() if g is not None).strip(), i))
    return keys


def detect_kind(text: str) -> str:
    """``"model"``, ``"process"``, ``"design"`` or ``"definition"``, by content."""
    text = text.lstrip("\ufeff")  # a BOM is not part of the first key
    keys = _top_level_keys(text)
    names = [k for k, _ in keys]
    if any(k in MODEL_KEYS for k in names):
        return "model"
    if "include" in names or any(k.startswith("define.") for k in names):
        return "process"
    if names and all(k.startswith("block.") for k in names):
        return "process"
    lines = text.splitlines()
    for n, (key, start) in enumerate(keys):
        if key.startswith("block."):
            end = keys[n + 1][1] if n + 1 < len(keys) else len(lines)
            for line in lines[start + 1 : end]:
                m = _INDENTED_KEY.match(line)
                if m and m.group(1) == "mri":
                    return "process"
            if re.search(r"[{,]\s*mri\s*:", lines[start]):
                return "process"
    if any(k in DESIGN_KINDS or k.startswith("fixed.") for k in names):
        return "design"
    return "definition"

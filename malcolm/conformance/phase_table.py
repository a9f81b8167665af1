"""The phase reference table: which phases each transition of a model runs.

A table is YAML: model file stem -> list of rows, each ``{trigger, source,
dest, phases}`` (``source`` a name or a list, ``phases`` in the order they
run, ``[]`` for none)::

    stateful:
      - {trigger: init, source: Disabled, dest: Resetting, phases: [Init]}
      - {trigger: reset, source: [Fault, Disabled], dest: Resetting, phases: []}

A model matches its table when they have the same transitions (by trigger,
source and dest) and each runs the table's phases in the table's order.
``python -m malcolm.conformance.phase_table MODEL...`` prints the table of
models as they are, to start a table from.
"""

from __future__ import annotations

import sys
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from malcolm.fsm import Model, ModelError, Problem, Transition, load_model

Key = tuple[str, str, str]  # trigger, source, dest


def _read(path: Path) -> tuple[Any, list[Problem]]:
    """The document and its problems, read as models are read (line-aware:
    mappings have ``line_of(key)``, sequences ``line_of(index)``)."""
    from malcolm import yamlio

    try:
        data, found = yamlio.load(path)
    except yamlio.YamlError as e:
        found, data = [e.problem], None
    return data, [Problem(p.file, p.line, p.message) for p in found]


def _is_map(value: Any) -> bool:
    return isinstance(value, dict) and hasattr(value, "line_of")


def _is_list(value: Any) -> bool:
    return isinstance(value, list) and hasattr(value, "line_of")


ROW_KEYS = ("trigger", "source", "dest", "phases")


@dataclass(frozen=True)
class PhaseRow:
    """One transition of one model in a phase table, and where it is."""

    model: str
    trigger: str
    source: str
    dest: str
    phases: tuple[str, ...]
    file: str
    line: int | None

    @property
    def key(self) -> Key:
        return (self.trigger, self.source, self.dest)

    def where(self) -> str:
        return self.file if self.line is None else f"{self.file}:{self.line}"


PhaseTable = dict[str, list[PhaseRow]]


def load_phase_table(path: str | Path) -> PhaseTable:
    """Read a table; :class:`ModelError` lists every problem (file:line)."""
    path = Path(path)
    file = str(path)
    data, problems = _read(path)
    table: PhaseTable = {}
    if data is not None and not _is_map(data):
        problems.append(Problem(file, 1, "a phase table maps model names to rows"))
        data = None
    for model, rows in (data or {}).items():
        line = data.line_of(model)
        if not _is_list(rows):
            problems.append(Problem(file, line, f"{model}: expected a list of rows"))
            continue
        table[str(model)] = []
        for i, row in enumerate(rows):
            table[str(model)] += _read_row(
                str(model), row, file, rows.line_of(i), problems
            )
    if problems:
        raise ModelError(problems)
    return table


def _names(value: object) -> list[str] | None:
    if isinstance(value, str) and value:
        return [value]
    if (
        isinstance(value, list)
        and value
        and all(isinstance(v, str) and v for v in value)
    ):
        return list(value)
    return None


def _read_row(
    model: str, row: object, file: str, line: int | None, problems: list[Problem]
) -> list[PhaseRow]:
    if not _is_map(row):
        problems.append(Problem(file, line, f"{model}: a row is a mapping"))
        return []
    bad = [k for k in row if k not in ROW_KEYS]
    missing = [k for k in ROW_KEYS if k not in row]
    if bad or missing:
        what = [f"unknown key {k!r}" for k in bad] + [f"no {k!r}" for k in missing]
        problems.append(
            Problem(file, line, f"{model}: {', '.join(what)} (rows have {ROW_KEYS})")
        )
        return []
    sources = _names(row["source"])
    phases = [] if row["phases"] == [] else _names(row["phases"])
    fields = (row["trigger"], row["dest"])
    if sources is None or phases is None or not all(_names(f) for f in fields):
        problems.append(
            Problem(
                file,
                line,
                f"{model}: trigger and dest are names, source a name or a list,"
                " phases a list",
            )
        )
        return []
    return [
        PhaseRow(model, row["trigger"], s, row["dest"], tuple(phases), file, line)
        for s in sources
    ]


def table_problems(model: Model, rows: Sequence[PhaseRow]) -> list[Problem]:
    """Where ``model`` and its table rows disagree: a transition the table
    lacks, a row the model lacks, or other phases or another order."""
    problems: list[Problem] = []
    by_key: dict[Key, PhaseRow] = {}
    for row in rows:
        if row.key in by_key:
            problems.append(
                Problem(row.file, row.line, f"{row.model}: {_text(row.key)} twice")
            )
        by_key[row.key] = row
    seen: set[Key] = set()
    for t in model.transitions:
        key = (t.trigger, t.source, t.dest)
        if key in seen:
            problems.append(
                Problem(
                    t.file,
                    t.line,
                    f"transition {t} appears twice (with other guards): the"
                    " phase table cannot tell them apart",
                )
            )
            continue
        seen.add(key)
        row = by_key.get(key)
        if row is None:
            problems.append(
                Problem(
                    t.file,
                    t.line,
                    f"transition {t} (phases {_list(t.phases)}) is not in the phase"
                    f" table for {model.name}",
                )
            )
        elif tuple(t.phases) != row.phases:
            problems.append(
                Problem(
                    t.file,
                    t.line,
                    f"transition {t} runs phases {_list(t.phases)}, but the phase"
                    f" table ({row.where()}) says {_list(row.phases)}"
                    + _declared_elsewhere(model, t),
                )
            )
    for key, row in by_key.items():
        if key not in seen:
            problems.append(
                Problem(
                    row.file,
                    row.line,
                    f"{row.model}: the phase table has {_text(key)}"
                    f" (phases {_list(row.phases)}), which model {model.name}"
                    f" ({model.path}) does not have",
                )
            )
    return problems


def _declared_elsewhere(model: Model, t: Transition) -> str:
    """Where the transition's phases come from, if not from its own file (an
    extending model's replace_phases)."""
    places = []
    for phase in t.phases:
        file, line = model.where("phase", phase)
        if file != t.file:
            places.append(f"{phase} at {file}:{line}" if line else f"{phase} in {file}")
    return f" (phases declared by {model.name}: {', '.join(places)})" if places else ""


def _text(key: Key) -> str:
    trigger, source, dest = key
    return f"transition {trigger} {source}->{dest}"


def _list(phases: Iterable[str]) -> str:
    return "[" + ", ".join(phases) + "]"


def dump_phase_table(models: dict[str, Model]) -> str:
    """The table of ``models`` (stem -> model) as they are, as YAML text: one
    row per trigger, dest and phases, with every source that has them."""
    lines = ["# Which phases each transition runs, in order (malcolm.conformance)."]
    for stem, model in models.items():
        lines.append(f"{stem}:")
        rows: dict[tuple[str, str, tuple[str, ...]], list[str]] = {}
        for t in model.transitions:
            rows.setdefault((t.trigger, t.dest, t.phases), []).append(t.source)
        for (trigger, dest, phases), sources in rows.items():
            source = sources[0] if len(sources) == 1 else _list(sources)
            lines.append(
                f"  - {{trigger: {trigger}, source: {source}, dest: {dest},"
                f" phases: {_list(phases)}}}"
            )
    return "\n".join(lines) + "\n"


def main(argv: Sequence[str] | None = None) -> int:
    """Print the phase table of the models named (file paths or stems)."""
    names = list(sys.argv[1:] if argv is None else argv)
    if not names:
        print("usage: python -m malcolm.conformance.phase_table MODEL...")
        return 2
    try:
        models = {Path(n).stem: load_model(n) for n in names}
    except ModelError as e:
        print(e, file=sys.stderr)
        return 1
    sys.stdout.write(dump_phase_table(models))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

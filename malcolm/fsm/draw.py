"""Pictures of a model: Mermaid stateDiagram-v2 and Graphviz dot."""

from __future__ import annotations

from .model import Model


def to_mermaid(model: Model) -> str:
    """A Mermaid ``stateDiagram-v2``; edges say ``trigger [guards] /phases``
    and busy states are styled ``busy``."""
    lines = ["stateDiagram-v2"]
    for info in model.states.values():
        if info.description:
            text = " ".join(info.description.split())
            lines.append(f"    {info.name} : {text}")
    lines.append(f"    [*] --> {model.initial}")
    for t in model.transitions:
        label = t.label().replace(":", " ")
        lines.append(f"    {t.source} --> {t.dest}: {label}")
    busy = [name for name in model.states if model.states[name].busy]
    if busy:
        lines.append("    classDef busy font-style:italic,stroke-dasharray:4 2")
        lines.append(f"    class {','.join(busy)} busy")
    return "\n".join(lines) + "\n"


def _quote(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def to_dot(model: Model) -> str:
    """A Graphviz ``digraph``; busy states are dashed, edges labelled like
    :func:`to_mermaid`."""
    lines = [
        f"digraph {_quote(model.name)} {{",
        "    rankdir=LR;",
        '    node [shape=box, style="rounded"];',
        '    "__initial__" [shape=point, label=""];',
    ]
    for info in model.states.values():
        attrs = [f"label={_quote(info.name)}"]
        if info.description:
            attrs.append(f"tooltip={_quote(info.description)}")
        if info.busy:
            attrs.append('style="rounded,dashed"')
        lines.append(f"    {_quote(info.name)} [{', '.join(attrs)}];")
    lines.append(f"    {_quote('__initial__')} -> {_quote(model.initial)};")
    for t in model.transitions:
        lines.append(
            f"    {_quote(t.source)} -> {_quote(t.dest)} [label={_quote(t.label())}];"
        )
    lines.append("}")
    return "\n".join(lines) + "\n"

"""The python snippets of docs/core.md and docs/channels.md run as written."""

import re
from pathlib import Path

import pytest

from malcolm.core.threads import guard_trips

DOCS = Path(__file__).resolve().parents[2] / "docs"
SNIPPET = re.compile(r"^```python\n(.*?)^```", re.S | re.M)


def snippets(name: str) -> list[str]:
    found = SNIPPET.findall((DOCS / name).read_text())
    assert found, f"docs/{name} has no python snippets"
    return found


@pytest.mark.parametrize("page", ["core.md", "channels.md"])
def test_the_snippets_run(page):
    namespace: dict = {"__name__": f"docs_{page}"}
    for i, code in enumerate(snippets(page)):
        exec(compile(code, f"docs/{page} snippet {i + 1}", "exec"), namespace)
    if page == "channels.md":  # its last snippet trips the guard on purpose
        assert len(guard_trips) == 1 and "C.counter" in guard_trips[0]
        guard_trips.clear()

"""Where a manager's designs live, and how they are written.

Designs are YAML files at ``<designs_dir>/<mri>/<name>.yaml`` in the design
document's format. Saving is atomic: the text goes to a temporary file in
the same directory, is flushed to disk, and replaces the old file in one
``os.replace``, so a crash at any moment leaves the old design or the new
one. Template designs (shipped read-only examples) are read from other
directories and can be loaded but never overwritten.

A manager reads and writes designs in a worker thread (:meth:`DesignStore.
read`, :meth:`DesignStore.write`), so other blocks stay live while a design
is parsed or flushed to disk.
"""

from __future__ import annotations

import asyncio
import os
import re
import tempfile
import time
from collections.abc import Iterable, Sequence
from dataclasses import asdict, fields
from pathlib import Path
from typing import Any

import yaml

from malcolm.core import BadValueError
from malcolm.parts.design import DESIGN_KINDS, Design, load_design

_KIND_OF = {cls: kind for kind, cls in DESIGN_KINDS.items()}
NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.\-]*")
#: longest design name: the file and its temporary name must fit in a
#: file name (255 bytes on common file systems)
MAX_NAME_LENGTH = 200


def check_name(mri: str, name: Any) -> str:
    """``name`` if it is a design name, else BadValueError saying why."""
    if not isinstance(name, str) or not NAME.fullmatch(name):
        raise BadValueError(
            f"{mri}: {name!r} is not a design name (letters, digits, _ . -,"
            " starting with a letter or digit)"
        )
    if len(name) > MAX_NAME_LENGTH:
        raise BadValueError(
            f"{mri}: a design name has at most {MAX_NAME_LENGTH} characters,"
            f" not {len(name)} ({name[:20]}...)"
        )
    return name


def dump_design(records: Iterable[Any]) -> str:
    """The YAML text of design records, one section per record, in order."""
    chunks = []
    for record in records:
        kind = _KIND_OF[type(record)]
        body = {f.name: getattr(record, f.name) for f in fields(record)}
        if "description" in body and not body["description"]:
            del body["description"]
        text = yaml.safe_dump(
            body, sort_keys=False, default_flow_style=False, indent=4, width=1000
        )
        indented = "".join(f"    {line}\n" for line in text.splitlines())
        chunks.append(f"{kind}:\n{indented}")
    return "\n".join(chunks)


def _mode_of(path: Path) -> int:
    try:
        return path.stat().st_mode & 0o7777
    except FileNotFoundError:
        umask = os.umask(0o022)
        os.umask(umask)
        return 0o666 & ~umask


def atomic_write(path: Path, text: str) -> None:
    """Replace ``path`` with ``text`` so that readers see old or new, never half."""
    path.parent.mkdir(parents=True, exist_ok=True)
    _remove_stale_temps(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            # mkstemp makes the file 0600: give it the old file's mode, or what
            # a new file gets (0666 less the umask), so others can still read it
            os.fchmod(f.fileno(), _mode_of(path))
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    dir_fd = os.open(path.parent, os.O_RDONLY)
    try:
        os.fsync(dir_fd)
    finally:
        os.close(dir_fd)


STALE_TEMP_SECONDS = 60.0


def _remove_stale_temps(path: Path) -> None:
    """Temp files of saves killed long ago (a live save's temp is left alone)."""
    now = time.time()
    for tmp in path.parent.glob(f".{path.name}.*.tmp"):
        try:
            if now - tmp.stat().st_mtime > STALE_TEMP_SECONDS:
                tmp.unlink()
        except OSError:
            pass


class WriteSeenThrough(asyncio.CancelledError):
    """The caller of :meth:`DesignStore.write` was cancelled while the file
    was written: ``path`` if it was written, else ``error`` says why not."""

    def __init__(self, path: Path | None, error: BaseException | None) -> None:
        super().__init__()
        self.path = path
        self.error = error


class DesignStore:
    """The designs of one manager: saved ones (writable) and templates (not)."""

    def __init__(
        self,
        mri: str,
        designs_dir: Path | str,
        template_dirs: Sequence[Path | str] = (),
    ) -> None:
        self.mri = mri
        self.dir = Path(designs_dir) / mri.replace(":", "_")
        self.template_dirs = [Path(d) for d in template_dirs]

    def _templates(self) -> dict[str, Path]:
        found: dict[str, Path] = {}
        for d in self.template_dirs:
            if d.is_dir():
                for p in sorted(d.glob("*.yaml")):
                    found.setdefault(p.stem, p)
        return found

    def names(self) -> list[str]:
        """Saved designs then templates, each sorted."""
        saved = (
            sorted(p.stem for p in self.dir.glob("*.yaml")) if self.dir.is_dir() else []
        )
        return saved + [n for n in self._templates() if n not in saved]

    def is_template(self, name: str) -> bool:
        return name in self._templates() and not (self.dir / f"{name}.yaml").exists()

    def path(self, name: str) -> Path:
        """The file of design ``name`` (saved, else a template)."""
        check_name(self.mri, name)
        saved = self.dir / f"{name}.yaml"
        if saved.exists():
            return saved
        template = self._templates().get(name)
        if template is not None:
            return template
        known = ", ".join(self.names()) or "none"
        raise BadValueError(f"{self.mri}: no design {name!r} (designs: {known})")

    def load(self, name: str) -> Design:
        return load_design(self.path(name))

    def save(self, name: str, records: Iterable[Any]) -> Path:
        path = self.check_writable(name)
        atomic_write(path, dump_design(records))
        return path

    async def read(self, name: str) -> Design:
        """:meth:`load` in a worker thread (the loop stays live)."""
        return await asyncio.to_thread(self.load, name)

    async def write(self, name: str, records: Iterable[Any]) -> Path:
        """:meth:`save` in a worker thread (the loop stays live).

        A write once begun is seen through: if the caller is cancelled
        meanwhile, it waits for the write to end and then raises
        :class:`WriteSeenThrough` (carrying the path, or the write's error),
        so that it knows whether the file changed and can finish its own
        work to match before giving way."""
        items = list(records)
        job = asyncio.ensure_future(asyncio.to_thread(self.save, name, items))
        try:
            return await asyncio.shield(job)
        except asyncio.CancelledError:
            pass
        while not job.done():
            try:
                await asyncio.shield(job)
            except asyncio.CancelledError:
                continue
        if job.exception() is not None:
            raise WriteSeenThrough(None, job.exception())
        raise WriteSeenThrough(job.result(), None)

    def check_writable(self, name: str) -> Path:
        """Where ``save(name)`` writes; BadValueError for a bad or template name."""
        check_name(self.mri, name)
        if name in self._templates():
            raise BadValueError(
                f"{self.mri}: design {name!r} is a read-only template; save under"
                " another name"
            )
        return self.dir / f"{name}.yaml"


def records_equal(a: Design, b: Design) -> bool:
    """Same records in the same order (for tests and ``modified``)."""
    return [asdict(r) for r in a.records] == [asdict(r) for r in b.records]

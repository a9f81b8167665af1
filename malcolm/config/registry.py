"""Which Python class or factory builds each kind of section.

:func:`lookup` tries, in order:

1. kinds registered with :func:`register` (a call or a decorator);
2. malcolm's built-in kinds (:func:`register_builtin`, made by
   ``malcolm.config.builtin``), which an explicit :func:`register` of the
   same kind replaces;
3. entry points in the group ``malcolm.sections`` whose name is the kind,
   e.g. ``parts.MyPart = mypkg.parts:MyPart`` in a package's metadata;
4. an import path in the section name: ``parts.mypkg.parts.MyPart`` imports
   ``mypkg.parts`` and takes ``MyPart``; ``parts.mypkg.parts:MyPart`` says
   where the module ends.

What an entry point or an import path names must be a class: a
:class:`~malcolm.controllers.base.Controller` subclass for ``controller.*``,
a :class:`~malcolm.parts.base.Part` subclass for every other namespace.
``parts.os.system`` is refused before anything is called; only importing a
module runs its code. Kinds registered in Python may be any factory.

The namespaces in :data:`LOADER_NAMESPACES` have a fixed meaning that the
definition loader handles itself; the registry serves every other section
(``ca.*``, ``parts.*``, ``fixed.*``...) and the classes named by
``controller.*``.
"""

from __future__ import annotations

import difflib
import importlib
import importlib.util
from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING, Any, TypeVar

from .errors import ConfigError, Problems
from .yamlsections import KIND_RE, Section, split_kind

if TYPE_CHECKING:  # imported when a kind is not built in (10 ms at start-up)
    import importlib.metadata

#: Entry point group searched for section kinds.
ENTRY_POINT_GROUP = "malcolm.sections"
#: Namespaces whose sections the loader interprets itself.
LOADER_NAMESPACES = frozenset({"init", "gui", "controller", "block", "client"})

F = TypeVar("F", bound=Callable[..., Any])

_registry: dict[str, Callable[..., Any]] = {}
_builtins: dict[str, Callable[..., Any]] = {}


def register(kind: str, factory: F | None = None) -> Any:
    """Register ``factory`` for ``kind``; without ``factory``, a decorator.

    >>> @register("parts.Hello")
    ... class HelloPart: ...

    Registering a different factory for a kind already taken is an error.
    """
    if not KIND_RE.fullmatch(kind) or "." not in kind:
        raise ValueError(f"invalid section kind {kind!r} (expected namespace.Name)")

    def decorate(f: F) -> F:
        existing = _registry.get(kind)
        if existing is not None and existing is not f:
            raise ValueError(f"section kind {kind!r} is already registered")
        _registry[kind] = f
        return f

    return decorate if factory is None else decorate(factory)


def register_builtin(kind: str, factory: Callable[..., Any]) -> None:
    """Register one of malcolm's own kinds, below explicit registrations."""
    if not KIND_RE.fullmatch(kind) or "." not in kind:
        raise ValueError(f"invalid section kind {kind!r} (expected namespace.Name)")
    _builtins[kind] = factory


def is_builtin(factory: Callable[..., Any]) -> bool:
    """True if ``factory`` is one of malcolm's own registered kinds."""
    return any(factory is builtin for builtin in _builtins.values())


def unregister(kind: str) -> None:
    """Forget an explicitly registered kind (for tests and reloading)."""
    _registry.pop(kind, None)


def _entry_points() -> list[importlib.metadata.EntryPoint]:
    import importlib.metadata

    return list(importlib.metadata.entry_points(group=ENTRY_POINT_GROUP))


def known_kinds() -> list[str]:
    """Every kind registered (explicitly, built in, by entry point), sorted."""
    return sorted(set(_registry) | set(_builtins) | {ep.name for ep in _entry_points()})


def lookup(kind: str, file: str = "<unknown>", line: int = 1) -> Callable[..., Any]:
    """The factory for ``kind``; ConfigError at ``file:line`` if none.

    A kind found by entry point or import path must name a class: a
    Controller subclass for ``controller.*``, a Part subclass for any other
    namespace. Anything else (a function such as ``os.system``, a class of
    another kind) is refused, and never called.
    """
    if kind in _registry:
        return _registry[kind]
    if kind in _builtins:
        return _builtins[kind]
    for ep in _entry_points():
        if ep.name == kind:
            try:
                found = ep.load()
            except Exception as error:
                raise ConfigError.at(
                    file,
                    line,
                    f"section type '{kind}': cannot load entry point "
                    f"'{ep.value}': {type(error).__name__}: {error}",
                ) from None
            origin = f" (entry point '{ep.value}')"
            return _required_class(kind, found, origin, file, line)
    factory = _import_path(kind, file, line)
    if factory is not None:
        return factory
    raise ConfigError.at(file, line, f"unknown section type '{kind}'" + _suggest(kind))


def _required_class(
    kind: str, found: Any, origin: str, file: str, line: int
) -> Callable[..., Any]:
    """``found`` if it is the class ``kind``'s namespace needs, else ConfigError."""
    from malcolm.controllers.base import Controller
    from malcolm.parts.base import Part

    base = Controller if split_kind(kind)[0] == "controller" else Part
    if isinstance(found, type) and issubclass(found, base):
        return found
    if isinstance(found, type):
        what = f"the class {found.__module__}.{found.__qualname__}"
    else:
        what = _describe(found)
    raise ConfigError.at(
        file,
        line,
        f"section type '{kind}'{origin} names {what}, not a {base.__name__} class "
        f"(a section names a registered section type or a {base.__name__} subclass)",
    )


def _describe(found: Any) -> str:
    if callable(found):
        name = getattr(found, "__qualname__", None) or type(found).__name__
        module = getattr(found, "__module__", None)
        return f"the function {module}.{name}" if module else f"the function {name}"
    return f"a value of type {type(found).__name__}"


def _suggest(kind: str) -> str:
    """A did-you-mean for ``kind``: a close name in its namespace, else a close
    kind in another namespace."""
    known = known_kinds()
    namespace, name = split_kind(kind)
    names = [n for ns, n in map(split_kind, known) if ns == namespace]
    match = difflib.get_close_matches(name, names, n=1)
    if match:
        return f" (did you mean '{namespace}.{match[0]}'?)"
    match = difflib.get_close_matches(kind, known, n=1, cutoff=0.85)
    return f" (did you mean '{match[0]}'?)" if match else ""


def served_by_registry(namespace: str) -> bool:
    """True if sections in ``namespace`` are built by a registered factory."""
    return namespace == "controller" or namespace not in LOADER_NAMESPACES


def check_kinds(sections: Iterable[Section]) -> None:
    """Look up every section outside the loader's namespaces.

    Raises one ConfigError listing every section whose type is unknown.
    """
    problems = Problems()
    for section in sections:
        if served_by_registry(section.namespace):
            with problems.collect():
                lookup(section.kind, section.file, section.line)
    problems.raise_if_any()


def _import_path(kind: str, file: str, line: int) -> Callable[..., Any] | None:
    """Resolve ``ns.pkg.module.Attr`` or ``ns.pkg.module:Attr``, if it is one."""
    _, name = split_kind(kind)
    if ":" in name:
        module_name, _, attr_path = name.partition(":")
        candidates = [(module_name, attr_path)]
    else:
        parts = name.split(".")
        candidates = [
            (".".join(parts[:i]), ".".join(parts[i:]))
            for i in range(len(parts) - 1, 0, -1)
        ]
    for module_name, attr_path in candidates:
        try:
            found = importlib.util.find_spec(module_name) is not None
        except (ImportError, ValueError):
            found = False
        except Exception as error:  # a parent package failed to import
            raise _import_failed(kind, module_name, error, file, line) from None
        if not found:
            continue
        try:
            obj: Any = importlib.import_module(module_name)
        except Exception as error:
            raise _import_failed(kind, module_name, error, file, line) from None
        try:
            for attr in attr_path.split("."):
                obj = getattr(obj, attr)
        except AttributeError:
            raise ConfigError.at(
                file,
                line,
                f"unknown section type '{kind}': module '{module_name}' "
                f"has no attribute '{attr_path}'",
            ) from None
        return _required_class(kind, obj, "", file, line)
    return None


def _import_failed(
    kind: str, module: str, error: Exception, file: str, line: int
) -> ConfigError:
    return ConfigError.at(
        file,
        line,
        f"section type '{kind}': importing '{module}' failed: "
        f"{type(error).__name__}: {error}",
    )

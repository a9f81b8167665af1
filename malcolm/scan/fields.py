"""Checked access to the fields of a generator dict, naming the path on error."""

from __future__ import annotations

import math
import numbers
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from .errors import GeneratorError

_MISSING: Any = object()


def join(path: str, key: str | int) -> str:
    """Return the path of ``key`` inside the item at ``path``."""
    if isinstance(key, int):
        return f"{path}[{key}]"
    return f"{path}.{key}" if path else key


def describe(value: Any) -> str:
    """A short description of a bad value for an error message."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str | numbers.Number):
        text = repr(value)
    elif isinstance(value, Mapping):
        return "a mapping"
    elif isinstance(value, Sequence):
        return f"a list of {len(value)}"
    else:
        text = type(value).__name__
    return text if len(text) <= 40 else text[:37] + "..."


def as_mapping(value: Any, path: str) -> Mapping[str, Any]:
    """Return ``value`` if it is a mapping, else raise naming ``path``."""
    if not isinstance(value, Mapping):
        raise GeneratorError(path, f"expected a mapping, got {describe(value)}")
    return value


def _is_list(value: Any) -> bool:
    return isinstance(value, Sequence) and not isinstance(value, str | bytes)


def _number(value: Any, path: str) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise GeneratorError(path, f"expected a number, got {describe(value)}")
    try:
        result = float(value)
    except OverflowError:
        result = math.inf
    if not math.isfinite(result):
        raise GeneratorError(path, f"expected a finite number, got {describe(value)}")
    return result


class Fields:
    """Read typed fields from one mapping of a generator description.

    Every getter raises `GeneratorError` naming the full path of the field when
    it is missing or of the wrong type. `check_no_extra` rejects unknown keys so
    that a misspelt field is not silently ignored.
    """

    def __init__(self, data: Any, path: str) -> None:
        self.data = as_mapping(data, path)
        self.path = path
        self._used: set[str] = set()

    def at(self, key: str | int) -> str:
        """Path of ``key`` inside this mapping."""
        return join(self.path, key)

    def raw(self, key: str, default: Any = _MISSING) -> Any:
        """The value of ``key`` unchecked; ``default`` if absent (required if not
        given)."""
        self._used.add(key)
        if key not in self.data:
            if default is _MISSING:
                raise GeneratorError(self.at(key), "missing required key")
            return default
        return self.data[key]

    def has(self, key: str) -> bool:
        """Whether ``key`` is present."""
        return key in self.data

    def string(self, key: str, default: Any = _MISSING) -> str:
        """A string field."""
        value = self.raw(key, default)
        if not isinstance(value, str):
            raise GeneratorError(
                self.at(key), f"expected a string, got {describe(value)}"
            )
        return value

    def boolean(self, key: str, default: Any = _MISSING) -> bool:
        """A true/false field."""
        value = self.raw(key, default)
        if not isinstance(value, bool):
            raise GeneratorError(
                self.at(key), f"expected true or false, got {describe(value)}"
            )
        return value

    def number(self, key: str, default: Any = _MISSING) -> float:
        """A finite real number."""
        return _number(self.raw(key, default), self.at(key))

    def positive_number(self, key: str, default: Any = _MISSING) -> float:
        """A finite number > 0."""
        value = self.number(key, default)
        if value <= 0:
            raise GeneratorError(
                self.at(key), f"expected a positive number, got {describe(value)}"
            )
        return value

    def positive_int(self, key: str, default: Any = _MISSING) -> int:
        """An integer >= 1 (an integral float such as 3.0 is accepted)."""
        value = self.raw(key, default)
        ok = isinstance(value, numbers.Integral) and not isinstance(value, bool)
        if (
            not ok
            and isinstance(value, float)
            and math.isfinite(value)
            and value.is_integer()
        ):
            ok = True
        if not ok or value < 1:
            raise GeneratorError(
                self.at(key), f"expected a positive integer, got {describe(value)}"
            )
        return int(value)

    def number_list(
        self, key: str, length: int | None = None, default: Any = _MISSING
    ) -> list[float]:
        """A list of numbers (a bare number counts as a list of one), optionally
        of an exact length."""
        value = self.raw(key, default)
        path = self.at(key)
        if not _is_list(value):
            if isinstance(value, numbers.Real) and not isinstance(value, bool):
                value = [value]
            else:
                raise GeneratorError(
                    path, f"expected a list of numbers, got {describe(value)}"
                )
        result = [_number(v, join(path, i)) for i, v in enumerate(value)]
        if length is not None and len(result) != length:
            raise GeneratorError(path, f"expected {length} numbers, got {len(result)}")
        return result

    def string_list(self, key: str, default: Any = _MISSING) -> list[str]:
        """A list of strings (a bare string counts as a list of one)."""
        value = self.raw(key, default)
        path = self.at(key)
        if isinstance(value, str):
            return [value]
        if not _is_list(value):
            raise GeneratorError(
                path, f"expected a list of strings, got {describe(value)}"
            )
        for i, v in enumerate(value):
            if not isinstance(v, str):
                raise GeneratorError(
                    join(path, i), f"expected a string, got {describe(v)}"
                )
        return list(value)

    def axes(self, key: str = "axes", count: int | None = None) -> list[str]:
        """A list of distinct, non-empty axis names, optionally of an exact
        count."""
        names = self.string_list(key)
        path = self.at(key)
        for i, name in enumerate(names):
            if not name:
                raise GeneratorError(join(path, i), "axis name must not be empty")
        if count is not None and len(names) != count:
            raise GeneratorError(path, f"expected {count} axes, got {len(names)}")
        seen: set[str] = set()
        for name in names:
            if name in seen:
                raise GeneratorError(path, f"axis {name!r} is given twice")
            seen.add(name)
        return names

    def items(self, key: str, default: Any = _MISSING) -> list[tuple[str, Any]]:
        """A list field, returned as (path, item) pairs."""
        value = self.raw(key, default)
        path = self.at(key)
        if not _is_list(value):
            raise GeneratorError(path, f"expected a list, got {describe(value)}")
        return [(join(path, i), v) for i, v in enumerate(value)]

    def check_no_extra(self, allowed: Iterable[str] = ()) -> None:
        """Raise if the mapping has a key that no getter asked for (nor is in
        ``allowed``)."""
        known = self._used | set(allowed)
        for key in self.data:
            if key not in known:
                raise GeneratorError(self.at(str(key)), "unknown key")

"""Metas: the type, description and display hints of an attribute or argument.

Each meta validates values (returning the canonical form, or raising
BadValueError with a message that names the problem) and converts itself to
the Malcolm structure as plain data (``to_dict``).

The array metas and TableMeta are in :mod:`malcolm.core.arrays` and are
re-exported here.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any, ClassVar

from .errors import BadValueError

NT_SCALAR = "epics:nt/NTScalar:1.0"
NT_SCALAR_ARRAY = "epics:nt/NTScalarArray:1.0"
NT_TABLE = "epics:nt/NTTable:1.0"

INT_RANGES = {
    "int8": (-(2**7), 2**7 - 1),
    "uint8": (0, 2**8 - 1),
    "int16": (-(2**15), 2**15 - 1),
    "uint16": (0, 2**16 - 1),
    "int32": (-(2**31), 2**31 - 1),
    "uint32": (0, 2**32 - 1),
    "int64": (-(2**63), 2**63 - 1),
    "uint64": (0, 2**64 - 1),
}
FLOAT_DTYPES = ("float32", "float64")
DTYPES = tuple(INT_RANGES) + FLOAT_DTYPES


def _describe(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


class Meta:
    """Base of all metas: description, tags, writeable, label."""

    typeid: ClassVar[str] = ""
    nt_typeid: ClassVar[str] = NT_SCALAR

    def __init__(
        self,
        description: str = "",
        tags: Iterable[str] = (),
        writeable: bool = False,
        label: str = "",
    ) -> None:
        self.description = description
        self.tags = tuple(tags)
        self.writeable = writeable
        self.label = label

    def validate(self, value: Any) -> Any:
        """Return ``value`` in canonical form or raise BadValueError."""
        return value

    def default(self) -> Any:
        return None

    def _common(self) -> dict[str, Any]:
        return {
            "typeid": self.typeid,
            "description": self.description,
            "tags": list(self.tags),
            "writeable": self.writeable,
            "label": self.label,
        }

    def to_dict(self) -> dict[str, Any]:
        return self._common()

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.description!r})"


FLOAT32_MAX = 3.4028234663852886e38


def _is_numpy(value: Any) -> bool:
    return hasattr(value, "dtype") and hasattr(value, "item")


def _parse_number(dtype: str, text: str) -> int | float:
    text = text.strip()
    try:
        if dtype in FLOAT_DTYPES:
            return float(text)
        try:
            return int(text, 0)
        except ValueError:
            pass
        try:
            return int(text)  # decimal with leading zeros, e.g. "010"
        except ValueError:
            return float(text)  # "5.0" for an integer dtype
    except ValueError:
        raise BadValueError(
            f"expected a number ({dtype}), got {_describe(text)}"
        ) from None


def _number(dtype: str, value: Any) -> int | float:
    if type(value) is float and dtype == "float64":
        return value  # the common case, as the checks below would give it
    if _is_numpy(value):
        if getattr(value, "ndim", 0) != 0 or str(value.dtype) == "bool":
            raise BadValueError(f"expected a number ({dtype}), got {_describe(value)}")
        value = value.item()
    if isinstance(value, str):
        value = _parse_number(dtype, value)
    elif isinstance(value, bool) or not isinstance(value, int | float):
        raise BadValueError(f"expected a number ({dtype}), got {_describe(value)}")
    if dtype in FLOAT_DTYPES:
        try:
            value = float(value)
        except OverflowError:
            raise BadValueError(f"{value} is out of range for {dtype}") from None
        if dtype == "float32" and math.isfinite(value) and abs(value) > FLOAT32_MAX:
            raise BadValueError(f"{value} is out of range for float32")
        return value
    if isinstance(value, float):
        if not value.is_integer():
            raise BadValueError(f"expected an integer ({dtype}), got {value!r}")
        value = int(value)
    lo, hi = INT_RANGES[dtype]
    if not lo <= value <= hi:
        raise BadValueError(f"{value} is out of range for {dtype} [{lo}, {hi}]")
    return int(value)


class NumberMeta(Meta):
    """A number with a dtype (int8..uint64, float32, float64) and display hints."""

    typeid = "malcolm:core/NumberMeta:1.0"

    def __init__(
        self,
        dtype: str = "float64",
        description: str = "",
        tags: Iterable[str] = (),
        writeable: bool = False,
        label: str = "",
        display: Mapping[str, Any] | None = None,
    ) -> None:
        if dtype not in DTYPES:
            raise BadValueError(f"unknown dtype {dtype!r}, expected one of {DTYPES}")
        super().__init__(description, tags, writeable, label)
        self.dtype = dtype
        self.display = dict(display or {})

    def validate(self, value: Any) -> int | float:
        if type(value) is not float or self.dtype != "float64":
            value = _number(self.dtype, value)  # (a float64's float is itself)
        display = self.display
        if not display:  # most metas: no limits to test
            return value
        lo = display.get("limitLow")
        hi = display.get("limitHigh")
        if lo is not None and hi is not None and lo < hi and not lo <= value <= hi:
            raise BadValueError(f"{value} is outside the limits [{lo}, {hi}]")
        return value

    def default(self) -> int | float:
        return 0.0 if self.dtype in FLOAT_DTYPES else 0

    def to_dict(self) -> dict[str, Any]:
        d = self._common()
        d["dtype"] = self.dtype
        display = {
            "typeid": "display_t",
            "limitLow": 0.0,
            "limitHigh": 0.0,
            "description": "",
            "precision": 8 if self.dtype in FLOAT_DTYPES else 0,
            "units": "",
        }
        display.update(self.display)
        d["display"] = display
        return d


class StringMeta(Meta):
    """A string."""

    typeid = "malcolm:core/StringMeta:1.0"

    def validate(self, value: Any) -> str:
        if value is None:
            return ""
        if not isinstance(value, str):
            raise BadValueError(f"expected a string, got {_describe(value)}")
        return value

    def default(self) -> str:
        return ""


_TRUE = {"true", "yes", "on", "1"}
_FALSE = {"false", "no", "off", "0"}


class BooleanMeta(Meta):
    """True or False (strings yes/no/true/false and 0/1 are accepted)."""

    typeid = "malcolm:core/BooleanMeta:1.0"

    def validate(self, value: Any) -> bool:
        if _is_numpy(value) and getattr(value, "ndim", 0) == 0:
            value = value.item()
        if isinstance(value, bool):
            return value
        if isinstance(value, int) and value in (0, 1):
            return bool(value)
        if isinstance(value, str) and value.strip().lower() in _TRUE | _FALSE:
            return value.strip().lower() in _TRUE
        raise BadValueError(f"expected a boolean, got {_describe(value)}")

    def default(self) -> bool:
        return False


class ChoiceMeta(Meta):
    """One of a list of strings (an index into the list is accepted too)."""

    typeid = "malcolm:core/ChoiceMeta:1.0"

    def __init__(
        self,
        choices: Sequence[str] = (),
        description: str = "",
        tags: Iterable[str] = (),
        writeable: bool = False,
        label: str = "",
    ) -> None:
        super().__init__(description, tags, writeable, label)
        self.choices = tuple(str(c) for c in choices)

    def validate(self, value: Any) -> str:
        if isinstance(value, str) and value in self.choices:
            return value
        if _is_numpy(value) and getattr(value, "ndim", 0) == 0:
            value = value.item()
        if isinstance(value, int) and not isinstance(value, bool):
            if 0 <= value < len(self.choices):
                return self.choices[value]
        if value is None or (value == "" and not self.choices):
            return self.default()  # no choices (yet): "" is the only value
        raise BadValueError(
            f"{_describe(value)} is not one of {', '.join(self.choices) or '(none)'}"
        )

    def default(self) -> str:
        return self.choices[0] if self.choices else ""

    def to_dict(self) -> dict[str, Any]:
        d = self._common()
        d["choices"] = list(self.choices)
        return d


class MapMeta(Meta):
    """Named elements plus which of them are required (a method's takes/returns)."""

    typeid = "malcolm:core/MapMeta:1.0"

    def __init__(
        self,
        elements: Mapping[str, Meta] | None = None,
        required: Iterable[str] = (),
        description: str = "",
    ) -> None:
        super().__init__(description)
        self.elements = dict(elements or {})
        self.required = tuple(required)

    def to_dict(self) -> dict[str, Any]:
        return {
            "typeid": self.typeid,
            "elements": {k: m.to_dict() for k, m in self.elements.items()},
            "required": list(self.required),
        }


class MethodMeta(Meta):
    """What a method takes and returns, with defaults."""

    typeid = "malcolm:core/MethodMeta:1.1"

    def __init__(
        self,
        takes: MapMeta | None = None,
        returns: MapMeta | None = None,
        defaults: Mapping[str, Any] | None = None,
        description: str = "",
        tags: Iterable[str] = (),
        writeable: bool = True,
        label: str = "",
    ) -> None:
        super().__init__(description, tags, writeable, label)
        self.takes = takes or MapMeta()
        self.returns = returns or MapMeta()
        self.defaults = dict(defaults or {})

    def validate_args(self, method: str, args: Mapping[str, Any]) -> dict[str, Any]:
        """Check call arguments, apply defaults; errors name ``method.arg``.

        An argument given as None counts as not given. Defaults are validated
        (and so copied) too, so a handler cannot change them by mutation.
        """
        # once per call of every method: the checks in C where they can be
        if type(args) is not dict and not isinstance(args, Mapping):
            raise BadValueError(
                f"{method}: arguments must be a mapping, got {_describe(args)}"
            )
        elements = self.takes.elements
        if not elements.keys() >= args.keys():
            unknown = [k for k in args if k not in elements]
            takes = ", ".join(elements) or "no arguments"
            raise BadValueError(
                f"{method}.{unknown[0]}: unknown argument (takes {takes})"
            )
        out: dict[str, Any] = {}
        defaults = self.defaults
        for name, meta in elements.items():
            value = args.get(name)
            if value is not None:
                try:
                    out[name] = meta.validate(value)
                except BadValueError as e:
                    raise BadValueError(f"{method}.{name}: {e}") from None
            elif name in defaults:
                default = defaults[name]
                if type(default) in _IMMUTABLE and default is not None:
                    try:  # nothing to copy (most defaults): _default in line
                        out[name] = meta.validate(default)
                    except BadValueError:
                        out[name] = default
                else:
                    out[name] = self._default(name, meta)
            elif name in self.takes.required:
                raise BadValueError(f"{method}.{name}: missing required argument")
        return out

    def _default(self, name: str, meta: Meta) -> Any:
        default = self.defaults[name]
        if default is None:
            return None
        if type(default) in _IMMUTABLE:  # nothing to copy (most defaults)
            try:
                return meta.validate(default)
            except BadValueError:
                return default
        try:
            return meta.validate(copy.deepcopy(default))
        except BadValueError:
            # a default that its own meta rejects is passed through unchanged,
            # as the handler's signature asked for it
            return copy.deepcopy(default)

    def to_dict(self) -> dict[str, Any]:
        d = self._common()
        d["takes"] = self.takes.to_dict()
        d["defaults"] = {k: _plain(v) for k, v in self.defaults.items()}
        d["returns"] = self.returns.to_dict()
        return d


class BlockMeta(Meta):
    """Description and field order of a block."""

    typeid = "malcolm:core/BlockMeta:1.0"

    def __init__(
        self,
        description: str = "",
        tags: Iterable[str] = (),
        writeable: bool = True,
        label: str = "",
        fields: Iterable[str] = (),
    ) -> None:
        super().__init__(description, tags, writeable, label)
        self.fields = list(fields)

    def to_dict(self) -> dict[str, Any]:
        d = self._common()
        d["fields"] = list(self.fields)
        return d


#: element types a list keeps as they are (a long list of them is copied in C)
_SCALARS = frozenset({float, int, str, bool, type(None)})
#: values a copy of which is the value itself
_IMMUTABLE = _SCALARS


def _plain(value: Any) -> Any:
    """Plain data for the wire: tuples become lists, numpy values Python ones."""
    kind = type(value)
    if kind in _SCALARS:  # the common case, without the ABC checks below
        return value
    if kind is dict:
        return {k: _plain(v) for k, v in value.items()}
    if kind is NumberArray:
        return list(value)  # Python numbers all: no check of each one's type
    if isinstance(value, tuple | list):
        if len(value) > 16 and _SCALARS.issuperset(map(type, value)):
            return list(value)  # e.g. a GDA array of positions: no call per item
        return [_plain(v) for v in value]
    if isinstance(value, Mapping):
        return {k: _plain(v) for k, v in value.items()}
    if _is_numpy(value):
        return _plain(value.tolist()) if getattr(value, "ndim", 0) else value.item()
    return value


plain = _plain


# The array metas and TableMeta live in .arrays, which builds on the metas
# above: imported last, so that those exist, and re-exported from here.
from .arrays import ArrayMeta as ArrayMeta  # noqa: E402
from .arrays import BooleanArrayMeta as BooleanArrayMeta  # noqa: E402
from .arrays import ChoiceArrayMeta as ChoiceArrayMeta  # noqa: E402
from .arrays import NumberArray as NumberArray  # noqa: E402
from .arrays import NumberArrayMeta as NumberArrayMeta  # noqa: E402
from .arrays import StringArrayMeta as StringArrayMeta  # noqa: E402
from .arrays import TableMeta as TableMeta  # noqa: E402

"""Core data model: blocks, attributes, methods, metas, alarms, the process."""

from .alarm import Alarm, AlarmSeverity, AlarmStatus
from .block import Block
from .errors import (
    AbortedError,
    BadValueError,
    MalcolmError,
    NotAllowedError,
    NotFoundError,
    NotWriteableError,
    PhaseTimeoutError,
    WaitTimeoutError,
)
from .fields import Attribute, Field, Method, MethodLog
from .generator import PointGeneratorMeta
from .longlived import long_lived
from .metas import (
    BlockMeta,
    BooleanArrayMeta,
    BooleanMeta,
    ChoiceArrayMeta,
    ChoiceMeta,
    MapMeta,
    Meta,
    MethodMeta,
    NumberArray,
    NumberArrayMeta,
    NumberMeta,
    StringArrayMeta,
    StringMeta,
    TableMeta,
)
from .process import Process, Subscription
from .serialize import apply_changes, from_dict, register_typeid, to_dict
from .threads import (
    OffLoopError,
    call_threadsafe,
    enable_loop_guard,
    loop_guard_enabled,
)
from .timestamp import TimeStamp

__all__ = [
    "AbortedError", "Alarm", "AlarmSeverity", "AlarmStatus", "Attribute",
    "BadValueError", "Block", "BlockMeta", "BooleanArrayMeta", "BooleanMeta",
    "ChoiceArrayMeta", "ChoiceMeta", "Field", "MalcolmError", "MapMeta", "Meta",
    "Method", "MethodLog", "MethodMeta", "NotAllowedError", "NotFoundError",
    "NotWriteableError", "NumberArray", "NumberArrayMeta", "NumberMeta", "OffLoopError",
    "PhaseTimeoutError", "PointGeneratorMeta", "Process", "StringArrayMeta",
    "StringMeta", "Subscription", "TableMeta", "TimeStamp", "WaitTimeoutError",
    "apply_changes", "call_threadsafe", "enable_loop_guard", "from_dict",
    "long_lived", "loop_guard_enabled", "register_typeid", "to_dict",
]  # fmt: skip


def __getattr__(name: str) -> object:
    # The design document imports these from malcolm.core; they live in
    # malcolm.parts (which imports malcolm.core), so load them lazily.
    if name in ("ChildControllerPart", "Controls"):
        from malcolm import parts

        return getattr(parts, name)
    raise AttributeError(f"module 'malcolm.core' has no attribute {name!r}")

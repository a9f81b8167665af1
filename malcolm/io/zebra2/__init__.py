"""Zebra2 (PandA) over TCP: the control port client, the box's layout, the
``*CHANGES`` and table formats, the polled :class:`Box` (docs/zebra2.md).
The data port client (``.data``, on the ``pandablocks`` library) and the
HDF5 writer (``.hdf``, h5py) are imported from their modules when used."""

from .box import Box
from .control import (
    DEFAULT_CONTROL_PORT,
    DEFAULT_DATA_PORT,
    DEFAULT_TIMEOUT,
    ControlClient,
    Reply,
    Zebra2Disconnected,
    Zebra2Error,
    Zebra2Timeout,
)
from .layout import (
    BlockLayout,
    BoxLayout,
    FieldLayout,
    TableColumn,
    instance_names,
    introspect,
)
from .values import Change, pack_table, parse_change, unpack_table

__all__ = [
    "DEFAULT_CONTROL_PORT",
    "DEFAULT_DATA_PORT",
    "DEFAULT_TIMEOUT",
    "BlockLayout",
    "BoxLayout",
    "Change",
    "Box",
    "ControlClient",
    "FieldLayout",
    "Reply",
    "TableColumn",
    "Zebra2Disconnected",
    "Zebra2Error",
    "Zebra2Timeout",
    "instance_names",
    "introspect",
    "pack_table",
    "parse_change",
    "unpack_table",
]

"""The list of a process's blocks, as a block a server serves (``localhost``).

pymalcolm's servers publish the mris they serve as the ``blocks``
attribute of a block called ``localhost``; ``malcolm ls`` reads it there.
:func:`add_block_list` adds such a block to a process (``malcolm serve`` and
``malcolm demo`` do when they serve pvAccess): ``health`` (OK), ``state``
(always Ready) and ``blocks``, a string array of every other block's mri in
the process's order, brought up to date when the process starts and
whenever a block is added or removed at run time (:func:`add_block_list`
has the process call :meth:`BlockList.refresh` then).

This is a small piece kept apart from the pvAccess server: the server
serves it like any block; a process without it makes ``malcolm ls`` say
that the server publishes no list of its blocks.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from malcolm.core import Attribute, Block, ChoiceMeta, StringArrayMeta, StringMeta

if TYPE_CHECKING:
    from malcolm.core import Process

__all__ = ["BLOCK_LIST_MRI", "BlockList", "add_block_list"]

#: the mri pymalcolm gives the block that lists a server's blocks
BLOCK_LIST_MRI = "localhost"


class BlockList:
    """A block whose ``blocks`` attribute lists its process's other blocks."""

    def __init__(self, mri: str = BLOCK_LIST_MRI) -> None:
        self.mri = mri
        self.process: Process | None = None
        self.block = Block(mri, "The blocks this process serves")
        self.health = Attribute("health", StringMeta("Why the block is in Fault"), "OK")
        self.block.add(self.health)
        self.state = Attribute("state", ChoiceMeta(["Ready"], "Always Ready"))
        self.block.add(self.state)
        self.blocks = Attribute(
            "blocks",
            StringArrayMeta("The mris of the blocks served", ("widget:table",)),
        )
        self.block.add(self.blocks)

    def refresh(self) -> None:
        """Set ``blocks`` to the process's mris (on the process's loop)."""
        if self.process is None or self.mri not in self.process.mris:
            return
        mris = tuple(m for m in self.process.mris if m != self.mri)
        if mris != self.blocks.value:
            self.blocks.set_value(mris)

    async def start(self) -> None:
        self.refresh()

    async def stop(self) -> None:
        """Nothing to let go of."""

    async def put(self, name: str, value: Any) -> None:
        from malcolm.core import NotWriteableError

        self.block.attribute(name)
        raise NotWriteableError(f"{self.mri}.{name} is read-only")

    async def call(self, name: str, params: Any = None) -> Any:
        self.block.method(name)  # NotFoundError: it has none

    def writer_of(self, field: str) -> str | None:
        return None


def add_block_list(process: Process, mri: str = BLOCK_LIST_MRI) -> BlockList:
    """Add a :class:`BlockList` to ``process`` (before it starts, or on its
    loop); returns it. Its list follows blocks added and removed later."""
    block_list = BlockList(mri)
    process.add_controller(block_list)  # type: ignore[arg-type]
    process.watch_hosting(block_list.refresh)
    block_list.refresh()
    return block_list

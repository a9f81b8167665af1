"""Parts: the building blocks users compose into blocks."""

from .base import ChildControllerPart, ChildPart, Controls, Part, PartRegistrar

__all__ = ["ChildControllerPart", "ChildPart", "Controls", "Part", "PartRegistrar"]

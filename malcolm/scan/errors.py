"""The one exception the scan package raises for bad generator input."""

from __future__ import annotations


class GeneratorError(ValueError):
    """A generator description (dict, Spec or file) is malformed or unusable.

    The message starts with the path of the offending item inside the input,
    e.g. ``generators[1].size: expected a positive integer, got -3`` or
    ``excluders[0]: unknown typeid 'x'``.

    Attributes:
        path: Where in the input the problem is ("" for the input as a whole).
        reason: What is wrong with it.
    """

    def __init__(self, path: str, reason: str) -> None:
        self.path = path
        self.reason = reason
        super().__init__(f"{path}: {reason}" if path else reason)

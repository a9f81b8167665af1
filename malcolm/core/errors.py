"""Exceptions raised by malcolm; each names what was wrong and where."""

from __future__ import annotations


class MalcolmError(Exception):
    """Base class of every error malcolm raises on purpose."""


class BadValueError(MalcolmError, ValueError):
    """A value does not fit a meta; the message names the field."""


class NotFoundError(MalcolmError, LookupError):
    """A block, field or path does not exist."""


class NotWriteableError(MalcolmError):
    """A put to a field that is read-only."""


class NotAllowedError(MalcolmError):
    """A call or put that the block's state-machine model does not allow now."""


class AbortedError(MalcolmError):
    """The operation was cancelled by abort() (or pause(), disable())."""


class PhaseTimeoutError(MalcolmError, TimeoutError):
    """A hook phase did not finish within its timeout."""


class WaitTimeoutError(MalcolmError, TimeoutError):
    """Task.when_matches (or a put) did not complete in time."""

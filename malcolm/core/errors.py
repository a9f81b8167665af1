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
    """A wait (a call, a put, when_matches...) gave up after its timeout.

    A call or put that timed out goes on (see :func:`still_running`).
    """


def still_running(what: str, timeout: float | None) -> WaitTimeoutError:
    """The error of a caller whose ``timeout`` expired: the operation goes on.

    The rule for every timeout of a method call or a put (docs/embedding.md):
    a timeout stops the caller waiting; it never cancels or undoes the
    operation on the block. To stop that, call abort() (or cancel it).
    """
    return WaitTimeoutError(
        f"{what} did not finish within {timeout} s; it goes on"
        " (the timeout only stopped the wait: call abort() to stop it)"
    )

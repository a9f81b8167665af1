"""A put whose circuit is lost before libca completes it fails as a
disconnection (the IOC went away), not as a refused value.

libca may report the lost circuit to the put's callback before the channel's
connection callback says so; the caller must see the same DisconnectedError
either way."""

from __future__ import annotations

import asyncio
from types import SimpleNamespace

from epics import dbr

from malcolm.io import ChannelError, DisconnectedError
from malcolm.io.ca import link
from malcolm.io.ca.backend import PyepicsChannel

ECA_DISCONN = 192  # caerr.h: "Virtual circuit disconnect"


def _completion(status: int) -> str:
    """What link's put-completion callback tells the channel for a status."""
    said: list[str] = []
    link._on_put(SimpleNamespace(status=status, usr=lambda _, e: said.append(e)))
    (error,) = said
    return error


def _settled(error: str) -> BaseException | None:
    async def scenario() -> BaseException | None:
        channel = PyepicsChannel("T:M1.RBV", "T:M1", None)
        channel._loop = asyncio.get_running_loop()
        fut = channel._future()
        channel._settle(fut, None, error, channel.write)  # as a put's done does
        return fut.exception()

    return asyncio.run(scenario())


def test_a_put_cut_off_by_the_lost_circuit_is_a_disconnection() -> None:
    error = _settled(_completion(ECA_DISCONN))
    assert isinstance(error, DisconnectedError)
    assert str(error).startswith("T:M1: ")  # the PV put to
    assert "Virtual circuit disconnect" in str(error)


def test_a_refused_put_is_still_a_channel_error_not_a_disconnection() -> None:
    ECA_PUTFAIL = 160  # caerr.h: "Channel write request failed"
    error = _settled(_completion(ECA_PUTFAIL))
    assert isinstance(error, ChannelError)
    assert not isinstance(error, DisconnectedError)
    assert str(error).startswith("T:M1: put failed")


def test_a_completed_put_is_no_error() -> None:
    assert _completion(dbr.ECA_NORMAL) == ""
    assert _settled("") is None


def test_the_status_is_libcas_own() -> None:
    from epics import ca

    assert ca.message(ECA_DISCONN) == "Virtual circuit disconnect"
    assert link.ECA_DISCONN == ECA_DISCONN

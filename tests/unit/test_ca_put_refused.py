"""A put that libca refuses before sending it, or whose PV's link is down
before the loop heard so, fails with the error of its kind naming the PV
put to (a motor's VAL, not its readback RBV).

``ca_array_put_callback`` returns a status at once: ECA_DISCONN when libca
knows the circuit is lost and the connection callback has not run yet (the
window the lead's fix for the put's completion closed, seen from the other
side), ECA_NOWTACCESS for a PV the IOC gives no write access to. Before,
both were a DisconnectedError naming the readback: a refused put looked
like a lost connection."""

from __future__ import annotations

import asyncio
from typing import Any

import pytest
from epics import ca, dbr

from malcolm.io import ChannelError, DisconnectedError
from malcolm.io.ca import link
from malcolm.io.ca.backend import PyepicsChannel

ECA_DISCONN = 192  # caerr.h: "Virtual circuit disconnect"
ECA_NOWTACCESS = 376  # caerr.h: "Write access denied"


def _put_with(monkeypatch: pytest.MonkeyPatch, status: int | None) -> Any:
    """The error of a channel's put (read T:M1.RBV, write T:M1) whose write
    link is connected as far as the channel knows, libca answering
    ``ca_array_put_callback`` with ``status`` (None: the link is down)."""
    link._context()  # libca loaded: its put call is replaced below
    monkeypatch.setattr(
        ca.libca, "ca_array_put_callback", lambda *args: status, raising=False
    )
    target = link.Link("T:M1")
    target.connected = status is not None
    target.ftype = dbr.DOUBLE

    async def scenario() -> Any:
        channel = PyepicsChannel("T:M1.RBV", "T:M1", 0.0)
        channel._links["T:M1"] = target
        channel._loop = asyncio.get_running_loop()
        try:
            await asyncio.wait_for(channel._put(1.0), 5)
        except ChannelError as e:
            return e
        return None

    return asyncio.run(scenario())


def test_a_put_libca_refuses_for_its_lost_circuit_is_a_disconnection(monkeypatch):
    error = _put_with(monkeypatch, ECA_DISCONN)
    assert isinstance(error, DisconnectedError)
    assert str(error).startswith("T:M1: ")  # the PV put to, not T:M1.RBV
    assert "Virtual circuit disconnect" in str(error)


def test_a_put_libca_refuses_for_no_write_access_is_not_a_disconnection(
    monkeypatch,
):
    error = _put_with(monkeypatch, ECA_NOWTACCESS)
    assert isinstance(error, ChannelError)
    assert not isinstance(error, DisconnectedError)
    assert str(error) == "T:M1: put failed: Write access denied"


def test_a_put_whose_link_is_down_names_the_pv_put_to(monkeypatch):
    error = _put_with(monkeypatch, None)
    assert isinstance(error, DisconnectedError)
    assert str(error) == "T:M1: not connected"

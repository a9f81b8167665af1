"""ca.* attributes on channels: their backend is chosen by configuration; a
lost connection makes the alarm INVALID and health name it, and both recover
on reconnection; a put completes, then shows what the readback says."""

import asyncio

import pytest

from malcolm.controllers.stateful import StatefulController
from malcolm.core import (
    Alarm,
    AlarmSeverity,
    AlarmStatus,
    NumberMeta,
    Process,
)
from malcolm.io import (
    ConnectionState,
    DisconnectedError,
    SoftBackend,
    backend_for,
    backend_names,
    register_backend,
    use_backend,
)
from malcolm.io.ca.backend import PyepicsBackend
from malcolm.parts.soft import CADoublePart, CAEnumPart

from .scans import run


def det_process(backend=None, **process_args):
    process = Process("ca", **process_args)
    parts = [
        CADoublePart("exposure", pv="BL:Exposure", rbv_suffix="_RBV", writeable=True),
        CAEnumPart("mode", pv="BL:Mode", writeable=True),
    ]
    process.add_controller(StatefulController("DRV", parts))
    if backend is not None:
        use_backend(process, "ca", backend)
    return process


def test_values_alarms_and_times_come_from_the_channel():
    backend = SoftBackend()
    backend.define("BL:Exposure_RBV", 0.5)

    async def scenario():
        process = det_process(backend)
        await process.start()
        block = process.get_block("DRV")
        assert block.exposure.value == 0.5 and block.exposure.alarm == Alarm.ok
        backend.set("BL:Exposure_RBV", 0.7, Alarm.minor("HIGH"))
        record = backend.records["BL:Exposure_RBV"]
        return (
            block.exposure.value,
            block.exposure.alarm,
            block.exposure.timeStamp,
            record,
        )

    value, alarm, stamp, record = run(scenario)
    assert (value, alarm, stamp) == (0.7, Alarm.minor("HIGH"), record.timeStamp)


def test_a_lost_connection_is_an_invalid_alarm_and_health_until_it_is_back():
    backend = SoftBackend()

    async def scenario():
        process = det_process(backend)
        await process.start()
        block = process.get_block("DRV")
        deltas = []
        process.subscribe(["DRV", "exposure", "alarm"], deltas.append)
        backend.drop("BL:Exposure_RBV")
        lost = (block.exposure.alarm, block.health.value, block.state.value)
        backend.set("BL:Exposure_RBV", 2.0)  # changed while we could not see
        backend.restore("BL:Exposure_RBV")
        back = (block.exposure.alarm, block.health.value, block.exposure.value)
        return lost, back, deltas

    lost, back, deltas = run(scenario)
    alarm, health, state = lost
    assert alarm.severity is AlarmSeverity.INVALID_ALARM
    assert alarm.status is AlarmStatus.CLIENT_STATUS
    assert "BL:Exposure_RBV: connection lost" in alarm.message
    assert health.startswith("exposure: ") and "BL:Exposure_RBV" in health
    assert state == "Ready"  # a part's problem is not a fault
    assert back == (Alarm.ok, "OK", 2.0)
    assert len(deltas) == 3  # initial, lost, back


def test_a_channel_that_does_not_connect_at_start_is_reported_and_recovers(
    monkeypatch,
):
    monkeypatch.setattr(CADoublePart, "connect_timeout", 0.05)
    backend = SoftBackend()
    backend.drop("BL:Exposure_RBV", "IOC not running")

    async def scenario():
        process = det_process(backend)
        await process.start()
        block = process.get_block("DRV")
        before = (block.state.value, block.health.value, block.exposure.alarm)
        backend.restore("BL:Exposure_RBV")
        return before, (block.health.value, block.exposure.alarm)

    (state, health, alarm), after = run(scenario)
    assert state == "Ready"
    assert "exposure: " in health and "IOC not running" in health
    assert alarm.severity is AlarmSeverity.INVALID_ALARM
    assert after == ("OK", Alarm.ok)


def test_a_connection_lost_again_at_once_does_not_stop_the_block(monkeypatch):
    from malcolm.io import SoftChannel

    backend = SoftBackend()
    connect = SoftChannel.connect

    async def lost(self, timeout=None):  # connects, and is lost at once
        info = await connect(self, timeout)
        backend.drop(self.read, "gone again")
        return info

    monkeypatch.setattr(SoftChannel, "connect", lost)

    async def scenario():
        process = det_process(backend)
        await process.start()
        block = process.get_block("DRV")
        return block.state.value, block.health.value, block.exposure.alarm.status

    state, health, status = run(scenario)
    assert state == "Ready" and "BL:Exposure_RBV: gone again" in health
    assert status is AlarmStatus.CLIENT_STATUS


def test_a_put_completes_then_shows_the_readback_not_a_late_monitor():
    backend = SoftBackend()
    backend.define("BL:Exposure_RBV", 0.0, follow=lambda demand: round(demand, 1))

    async def scenario():
        process = det_process(backend)
        await process.start()
        backend.hold_monitors("BL:Exposure_RBV")  # the monitor lags the put
        gets = backend.records["BL:Exposure_RBV"].gets
        await process.put(["DRV", "exposure"], 0.123)
        block = process.get_block("DRV")
        return block.exposure.value, backend.records["BL:Exposure_RBV"].gets - gets

    value, gets = run(scenario)
    assert value == 0.1  # the readback, read by a get after completion
    assert gets == 1
    assert backend.records["BL:Exposure"].value == 0.123
    assert backend.records["BL:Exposure"].puts == 1


def test_a_put_waits_for_completion():
    backend = SoftBackend()

    async def scenario():
        process = det_process(backend)
        await process.start()
        backend.hold_puts("BL:Exposure")
        putting = asyncio.ensure_future(process.put(["DRV", "exposure"], 3.0))
        for _ in range(5):
            await asyncio.sleep(0)
        before = (putting.done(), process.get_block("DRV").exposure.value)
        backend.release_puts("BL:Exposure")
        await putting
        return before, process.get_block("DRV").exposure.value

    assert run(scenario) == ((False, 0.0), 3.0)


def test_a_put_while_disconnected_names_the_pv_and_changes_nothing():
    backend = SoftBackend()

    async def scenario():
        process = det_process(backend)
        await process.start()
        backend.drop("BL:Exposure")
        block = process.get_block("DRV")
        with pytest.raises(DisconnectedError, match="BL:Exposure: connection lost"):
            await process.put(["DRV", "exposure"], 1.0)
        return block.exposure.value, block.state.value

    assert run(scenario) == (0.0, "Ready")
    assert backend.records["BL:Exposure"].puts == 0


def test_a_put_before_the_block_started_is_refused():
    process = det_process(SoftBackend())
    with pytest.raises(DisconnectedError, match="the block has not started"):
        run(lambda: process.put(["DRV", "exposure"], 1.0))


def test_the_meta_takes_what_the_channel_reports_where_the_definition_is_silent():
    backend = SoftBackend()
    backend.define("BL:Exposure_RBV", 2.0, limits=(0, 5), units="s", precision=4)
    backend.define("BL:Mode", "Fast", choices=["Slow", "Fast"])

    async def scenario():
        process = Process("ca")
        parts = [
            CADoublePart("exposure", pv="BL:Exposure", rbv_suffix="_RBV", units="ms"),
            CAEnumPart("mode", pv="BL:Mode"),
            CAEnumPart("fixed", pv="BL:Mode", choices=["A", "B", "Fast"]),
        ]
        process.add_controller(StatefulController("DRV", parts))
        use_backend(process, "ca", backend)
        await process.start()
        return process.get_block("DRV")

    block = run(scenario)
    display = block.exposure.meta.display
    assert (display["limitLow"], display["limitHigh"]) == (0, 5)
    assert display["precision"] == 4
    assert display["units"] == "ms"  # the definition's, not the channel's
    assert block.exposure.value == 2.0
    assert block.mode.meta.choices == ("Slow", "Fast") and block.mode.value == "Fast"
    assert block.fixed.meta.choices == ("A", "B", "Fast")


def test_disable_closes_the_channel_and_reset_opens_another():
    backend = SoftBackend()

    async def scenario():
        process = det_process(backend)
        await process.start()
        controller = process.get_controller("DRV")
        part = controller.parts["exposure"]
        first = part.channel
        await process.post(["DRV", "disable"])
        closed = (first.state, controller.block.exposure.alarm.status)
        await process.post(["DRV", "reset"])
        backend.set("BL:Exposure_RBV", 4.0)
        return closed, part.channel is not first, controller.block.exposure

    (state, status), renewed, exposure = run(scenario)
    assert state is ConnectionState.CLOSED and status is AlarmStatus.CLIENT_STATUS
    assert renewed and exposure.value == 4.0 and exposure.alarm == Alarm.ok


def test_process_stop_closes_the_backends():
    backend = SoftBackend()

    async def scenario():
        process = det_process(backend)
        await process.start()
        channel = process.get_controller("DRV").parts["exposure"].channel
        await process.stop()
        return channel.state

    assert run(scenario) is ConnectionState.CLOSED


# ---- choosing the backend


class Recording(SoftBackend):
    name = "recording"


register_backend("ca", "recording", Recording)


def test_the_backend_is_chosen_per_process(monkeypatch):
    monkeypatch.delenv("MALCOLM_CA_BACKEND", raising=False)
    # the default: pyepics (it imports here)
    assert type(backend_for(Process(), "ca")) is PyepicsBackend
    chosen = backend_for(Process(channels={"ca": "recording"}), "ca")
    assert type(chosen) is Recording
    monkeypatch.setenv("MALCOLM_CA_BACKEND", "recording")
    assert type(backend_for(Process(), "ca")) is Recording
    # the process's own choice beats the environment
    assert type(backend_for(Process(channels={"ca": "soft"}), "ca")) is SoftBackend
    process = Process()
    mine = SoftBackend()
    assert use_backend(process, "ca", mine) is mine
    assert backend_for(process, "ca") is mine
    assert set(backend_names("ca")) >= {"soft", "recording"}
    assert backend_names("zebra2") == ["soft"]


def test_an_unknown_backend_faults_the_block_naming_it(monkeypatch):
    monkeypatch.delenv("MALCOLM_CA_BACKEND", raising=False)

    async def scenario():
        process = det_process(channels={"ca": "nosuch"})
        await process.start()
        block = process.get_block("DRV")
        return block.state.value, block.health.value

    state, health = run(scenario)
    assert state == "Fault"
    assert "no 'ca' channel backend called 'nosuch' (there are: soft" in health


def test_a_definition_is_untouched_by_the_backend():
    meta = CADoublePart("x", pv="P", low=0, high=1).meta
    assert isinstance(meta, NumberMeta) and meta.display["limitHigh"] == 1

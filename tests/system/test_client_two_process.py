"""Two processes (issue 9's acceptance): process B's manager uses blocks of
process A through ``client.`` sections with ``fullname: pva://HOST:PORT/MRI``
and runs a scan through them; killing A shows INVALID alarms and ``health``
in B within a bounded time; restarting A recovers B, which was never
restarted, and B scans again. A is the demo served in a subprocess
(test_client_cli.serve_demo); B runs here, on this test's loop.
"""

from __future__ import annotations

import asyncio
import os
import signal

import pytest

from malcolm.config.build import build_definition
from malcolm.core import (
    AbortedError,
    AlarmSeverity,
    AlarmStatus,
    MalcolmError,
    NotAllowedError,
    Process,
)
from malcolm.scan import gda

from .test_client_cli import free_port, serve_demo, stop

#: how long B may take to see A gone (A's sockets close when it dies)
LOST_WITHIN = 10.0
#: how long B may take to find A again (it tries A's port every 0.5 s)
BACK_WITHIN = 40.0

B_DEFINITION = """\
controller.RunnableController:
    description: B's scan of A's detector and motor

client.demo.Detector:
    name: DET
    fullname: pva://127.0.0.1:{port}/DET1
    part: RunnableChildPart

client.demo.Motor:
    name: x
    fullname: pva://127.0.0.1:{port}/MOTOR:X
    part: MotorMovePart
    axis: x
"""


async def wait_for(predicate, what: str, timeout: float) -> None:
    loop = asyncio.get_running_loop()
    end = loop.time() + timeout
    while not predicate():
        if loop.time() > end:
            raise AssertionError(f"not within {timeout} s: {what}")
        await asyncio.sleep(0.05)


async def scan(process: Process, size: int) -> None:
    generator = gda.compound(gda.line("x", size, start=0, stop=2), duration=0.01)
    await process.post(
        ["BSCAN", "configure"], {"generator": generator, "axesToMove": ["x"]}
    )
    await process.post(["BSCAN", "run"])


def test_a_manager_scans_through_blocks_of_another_process(tmp_path):
    port = free_port()
    definition = tmp_path / "B.yaml"
    definition.write_text(B_DEFINITION.format(port=port))
    a = serve_demo(port)
    b = build_definition(definition, mri="BSCAN")
    assert b.mris == ["DET1", "MOTOR:X", "BSCAN"]

    async def main():
        nonlocal a
        await b.start()
        try:
            det, motor, manager = (b.get_block(m) for m in b.mris)
            assert det.state.value == "Ready" and manager.state.value == "Ready"
            # a scan through A: B's manager configures and runs A's DET1
            await scan(b, 5)
            assert manager.state.value == "Finished"
            assert manager.completedSteps.value == 5
            await wait_for(lambda: det.completedSteps.value == 5, "DET1 done", 10)
            assert det.state.value == "Finished" and det.totalSteps.value == 5
            await wait_for(lambda: motor.position.value == 2.0, "x at 2", 10)

            # A dies: every attribute of its mirrors INVALID, health says so
            stop(a)
            lost = f"pva://127.0.0.1:{port}/DET1: connection lost"
            await wait_for(lambda: det.health.value == lost, lost, LOST_WITHIN)
            for block in (det, motor):
                for name, attr in block.attributes.items():
                    assert attr.alarm.severity is AlarmSeverity.INVALID_ALARM, name
                    assert attr.alarm.status is AlarmStatus.CLIENT_STATUS, name
            assert motor.health.value.endswith("MOTOR:X: connection lost")
            assert not det.configure.meta.writeable  # nothing can be called

            # A comes back (new values): B's mirrors refresh, alarms clear
            a = serve_demo(port)
            await wait_for(lambda: det.health.value == "OK", "DET1 back", BACK_WITHIN)
            await wait_for(lambda: motor.health.value == "OK", "x back", BACK_WITHIN)
            assert det.state.value == "Ready" and det.completedSteps.value == 0
            assert motor.position.value == 0.0
            for block in (det, motor):
                for name, attr in block.attributes.items():
                    assert attr.alarm.severity is AlarmSeverity.NO_ALARM, name
            assert det.configure.meta.writeable

            # and B, never restarted, scans through it again
            await scan(b, 3)
            assert manager.state.value == "Finished"
            assert manager.completedSteps.value == 3
            await wait_for(lambda: det.completedSteps.value == 3, "DET1 done", 10)
        finally:
            await b.stop()

    try:
        asyncio.run(main())
    finally:
        stop(a)


DET_ONLY = """\
controller.RunnableController:
    description: B's scan of A's detector

client.demo.Detector:
    name: DET
    fullname: pva://127.0.0.1:{port}/DET1
    part: RunnableChildPart
"""


def det_only(tmp_path, port: int) -> Process:
    definition = tmp_path / "B.yaml"
    definition.write_text(DET_ONLY.format(port=port))
    return build_definition(definition, mri="BSCAN")


async def configure(process: Process, size: int, duration: float) -> None:
    generator = gda.compound(gda.line("x", size), duration=duration)
    await process.post(
        ["BSCAN", "configure"], {"generator": generator, "axesToMove": ["x"]}
    )


def test_pause_resume_abort_reset_of_a_remote_child(tmp_path):
    port = free_port()
    a = serve_demo(port)
    b = det_only(tmp_path, port)

    async def main():
        await b.start()
        try:
            det, manager = b.get_block("DET1"), b.get_block("BSCAN")
            await configure(b, 40, 0.05)
            assert det.state.value == "Armed" and det.totalSteps.value == 40
            run = asyncio.ensure_future(b.post(["BSCAN", "run"]))
            await wait_for(lambda: det.completedSteps.value >= 3, "3 steps", 20)
            await b.post(["BSCAN", "pause"], {"lastGoodStep": 2})
            assert manager.state.value == "Paused"
            await wait_for(lambda: det.state.value == "Paused", "DET1 Paused", 10)
            assert det.completedSteps.value == 2
            assert not run.done()  # the run waits for resume
            await b.post(["BSCAN", "resume"])
            await asyncio.wait_for(run, 30)
            assert manager.state.value == "Finished"
            await wait_for(lambda: det.state.value == "Finished", "DET1 done", 10)
            assert det.completedSteps.value == 40

            await configure(b, 40, 0.05)
            run = asyncio.ensure_future(b.post(["BSCAN", "run"]))
            await wait_for(lambda: det.completedSteps.value >= 2, "2 steps", 20)
            await b.post(["BSCAN", "abort"])
            with pytest.raises(AbortedError):
                await run
            assert manager.state.value == "Aborted"
            await wait_for(lambda: det.state.value == "Aborted", "DET1 Aborted", 10)
            await b.post(["BSCAN", "reset"])
            assert manager.state.value == "Ready"
            await wait_for(lambda: det.state.value == "Ready", "DET1 Ready", 10)
            # a remote refusal comes back as its own error, with its text
            with pytest.raises(NotAllowedError, match=r"DET1: run\(\) is not allowed"):
                await b.post(["DET1", "run"])
        finally:
            await b.stop()

    try:
        asyncio.run(main())
    finally:
        stop(a)


def test_a_server_lost_in_the_middle_of_a_scan(tmp_path):
    port = free_port()
    a = serve_demo(port)
    b = det_only(tmp_path, port)

    async def main():
        nonlocal a
        await b.start()
        try:
            det, manager = b.get_block("DET1"), b.get_block("BSCAN")
            await configure(b, 200, 0.05)
            run = asyncio.ensure_future(b.post(["BSCAN", "run"]))
            await wait_for(lambda: det.completedSteps.value >= 2, "2 steps", 20)
            stop(a)
            with pytest.raises(MalcolmError, match="DET1"):
                await asyncio.wait_for(run, LOST_WITHIN)
            assert manager.state.value == "Fault"
            assert "DET1" in manager.health.value
            assert det.health.value.endswith("DET1: connection lost")
            # A again: B's manager resets (never restarted) and scans again
            a = serve_demo(port)
            await wait_for(lambda: det.health.value == "OK", "DET1 back", BACK_WITHIN)
            await b.post(["BSCAN", "reset"])
            assert manager.state.value == "Ready"
            await configure(b, 4, 0.01)
            await b.post(["BSCAN", "run"])
            assert manager.state.value == "Finished"
        finally:
            await b.stop()

    try:
        asyncio.run(main())
    finally:
        stop(a)


def test_a_server_that_stops_answering(tmp_path):
    """A server that hangs (SIGSTOP: its sockets stay open) is seen as lost
    once p4p's echo goes unanswered (CONN_TMO), and found when it answers."""
    port = free_port()
    a = serve_demo(port)
    b = det_only(tmp_path, port)

    async def main():
        await b.start()
        try:
            det = b.get_block("DET1")
            assert det.health.value == "OK"
            os.kill(a.proc.pid, signal.SIGSTOP)
            lost = f"pva://127.0.0.1:{port}/DET1: connection lost"
            await wait_for(lambda: det.health.value == lost, lost, LOST_WITHIN)
            assert det.state.alarm.severity is AlarmSeverity.INVALID_ALARM
            os.kill(a.proc.pid, signal.SIGCONT)
            await wait_for(lambda: det.health.value == "OK", "DET1 back", BACK_WITHIN)
            assert det.state.alarm.severity is AlarmSeverity.NO_ALARM
            await configure(b, 2, 0.01)
            await b.post(["BSCAN", "run"])
            assert b.get_block("BSCAN").state.value == "Finished"
        finally:
            await b.stop()

    try:
        asyncio.run(main())
    finally:
        if a.proc.poll() is None:
            os.kill(a.proc.pid, signal.SIGCONT)
        stop(a)

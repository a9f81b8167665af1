"""Blocks added and removed while served, and bad connections (an
in-process server on free ports, a p4p client)."""

from __future__ import annotations

import queue
import socket
from typing import Any

import pytest
from p4p.client.thread import Disconnected, TimeoutError

from malcolm.controllers.stateful import StatefulController
from malcolm.core import Process
from malcolm.parts.demo import CounterPart

from .conftest import served_in_process
from .p4p_monitor import monitor


@pytest.fixture
def served():
    process = Process("runtime")
    process.add_controller(StatefulController("FIRST", [CounterPart("counter")]))
    with served_in_process(process) as (tp, server, ctx):
        yield tp, process, server, ctx


def add_block(process: Process, mri: str) -> None:
    controller = StatefulController(mri, [CounterPart("counter")])

    async def add() -> None:
        process.add_controller(controller)
        await controller.start()

    process.call_threadsafe(add).result(10)


def remove_block(process: Process, mri: str) -> None:
    async def remove() -> None:
        await process.get_controller(mri).stop()
        process.remove_controller(mri)

    process.call_threadsafe(remove).result(10)


def next_value(updates: queue.Queue[object]) -> Any:
    """The next update that is a value (not the Disconnected a monitor with
    notify_disconnect starts with)."""
    while isinstance(got := updates.get(timeout=10), Exception):
        pass
    return got


def test_a_block_added_at_run_time_appears(served):
    tp, process, server, ctx = served
    assert ctx.get("FIRST", timeout=5)["state.value"] == "Ready"
    with pytest.raises(TimeoutError):
        ctx.get("LATER", timeout=0.5)  # searched for before it exists
    add_block(process, "LATER")
    assert ctx.get("LATER", timeout=10)["state.value"] == "Ready"
    assert ctx.get("LATER.counter", timeout=5)["value"] == 0.0


def test_a_block_removed_at_run_time_disappears(served):
    tp, process, server, ctx = served
    add_block(process, "GOING")
    updates: queue.Queue[object] = queue.Queue()
    sub = monitor(ctx, "GOING.counter", updates.put, notify_disconnect=True)
    try:
        assert next_value(updates)["value"] == 0.0
        remove_block(process, "GOING")
        assert isinstance(updates.get(timeout=10), Disconnected)
    finally:
        sub.close()
    with pytest.raises(TimeoutError):
        ctx.get("GOING", timeout=0.5)
    assert "GOING" not in process.mris
    assert not [n for n in server.channel_names if n.startswith("GOING")]
    assert ctx.get("FIRST", timeout=5)["state.value"] == "Ready"  # others stay


def test_a_field_added_at_run_time_reshapes_the_block_channel(served):
    tp, process, server, ctx = served
    from malcolm.core import Attribute, NumberMeta

    updates: queue.Queue[object] = queue.Queue()
    sub = monitor(ctx, "FIRST", updates.put, notify_disconnect=True)
    try:
        assert "extra" not in next_value(updates).keys()
        block = process.get_block("FIRST")
        attr = Attribute("extra", NumberMeta("int32"))
        process.call_threadsafe(block.add, attr).result(5)
        while "extra" not in (got := next_value(updates)).keys():
            pass  # the channel is reopened with the new type
        assert got["extra"].getID() == "epics:nt/NTScalar:1.0"
        assert "extra" in got["meta.fields"]
    finally:
        sub.close()


def test_raw_tcp_connect_and_close_never_wedges_it(served):
    tp, process, server, ctx = served
    port = int(server.address.rsplit(":", 1)[1])
    for n in range(200):
        with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
            if n % 2:
                s.sendall(b"\xca\x02\x00\x01garbage that is not pvAccess" * 3)
    # and one left open, silent, while others work
    idle = socket.create_connection(("127.0.0.1", port), timeout=5)
    try:
        assert ctx.get("FIRST.state", timeout=5)["value"] == "Ready"
        ctx.put("FIRST.counter", 3, timeout=5)
        assert ctx.get("FIRST.counter", timeout=5)["value"] == 3.0
    finally:
        idle.close()


def test_the_block_list_follows_blocks_added_and_removed(served):
    from malcolm.io.pva.client_blocklist import add_block_list

    tp, process, server, ctx = served
    process.call_threadsafe(add_block_list, process).result(10)
    updates: queue.Queue[object] = queue.Queue()
    sub = monitor(ctx, "localhost.blocks", updates.put, notify_disconnect=True)
    try:
        assert list(next_value(updates)["value"]) == ["FIRST"]
        add_block(process, "LATER")
        assert list(next_value(updates)["value"]) == ["FIRST", "LATER"]
        remove_block(process, "FIRST")
        assert list(next_value(updates)["value"]) == ["LATER"]
        assert list(ctx.get("localhost.blocks", timeout=5)["value"]) == ["LATER"]
    finally:
        sub.close()


def test_p4p_is_imported_without_setuptools_which_still_imports_whole():
    import subprocess
    import sys

    code = (
        "import sys, malcolm.io.pva\n"
        "print('setuptools' in sys.modules, 'setuptools_dso' in sys.modules)\n"
        "import setuptools_dso\n"
        "print(callable(setuptools_dso.setup), callable(setuptools_dso.find_dso))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["False", "False", "True", "True"]


def test_a_released_channel_reuses_its_pv_and_serves_current_values(
    served, monkeypatch
):
    import time

    from p4p.client.thread import Context

    import malcolm.io.pva.server as server_module

    monkeypatch.setattr(server_module, "RELEASE_DELAY", 0.1)
    tp, process, server, ctx = served
    conf = ctx.conf()
    for round_ in range(3):
        other = Context("pva", conf=conf, useenv=False, nt=False)
        updates: queue.Queue[object] = queue.Queue()
        sub = monitor(other, "FIRST.counter", updates.put, notify_disconnect=True)
        assert next_value(updates)["value"] == float(round_)
        process.call_threadsafe(
            process.get_block("FIRST").counter.set_value, float(round_ + 1)
        ).result(5)
        assert next_value(updates)["value"] == float(round_ + 1)
        sub.close()
        other.close()
        deadline = time.monotonic() + 10
        # released: no channel of the name, its PV closed and kept for the
        # next (kept just after the channel is dropped: wait for both)
        while (
            "FIRST.counter" in server.channel_names
            or "FIRST.counter" not in server._kept
        ):
            assert time.monotonic() < deadline, "the channel was never released"
            time.sleep(0.05)

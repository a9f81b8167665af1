"""malcolm.embed: the demo process driven from plain threads."""

from __future__ import annotations

import asyncio
import threading
import time
from concurrent.futures import ThreadPoolExecutor

import pytest

from malcolm.core import (
    AbortedError,
    BadValueError,
    NotAllowedError,
    NotFoundError,
    WaitTimeoutError,
)
from malcolm.embed import ThreadedProcess, running, start_process

# malcolm.demo is imported lazily: serve_demo() binds sys.stdout as a default
# argument when the module is first imported, so importing it while pytest
# collects would hide `malcolm demo` output from test_demo's capsys.


def demo_process():
    from malcolm.demo import demo_process

    return demo_process()


def demo_generator(*args):
    from malcolm.demo import demo_generator

    return demo_generator(*args)


@pytest.fixture
def tp():
    tp = start_process(demo_process(), timeout=10)
    yield tp
    tp.stop(timeout=10)


def test_start_brings_every_block_to_ready(tp):
    assert tp.started
    assert set(tp.mris) >= {"HELLO", "COUNTER", "SCAN", "DET1"}
    for mri in tp.mris:
        assert tp.block(mri).state.value == "Ready"


def test_greet_returns_what_the_method_returns(tp):
    hello = tp.block("HELLO")
    assert hello.greet(name="x") == {"greeting": "Hello x"}
    assert hello["greet"](name="y", sleep=0.01) == {"greeting": "Hello y"}
    assert hello.greet.call({"name": "z"}, timeout=5) == {"greeting": "Hello z"}


def test_counter_put_and_increment(tp):
    counter = tp.block("COUNTER")
    counter.counter.put(3)
    assert counter.counter.value == 3.0
    counter.delta.put(2.5)
    counter.increment()
    assert counter.counter.value == 5.5
    counter.zero()
    assert tp.get(["COUNTER", "counter", "value"]) == 0.0
    tp.put(["COUNTER", "counter"], 7)
    assert counter.counter.to_dict()["value"] == 7.0


def test_subscribe_delivers_current_value_then_changes_in_order(tp):
    counter = tp.block("COUNTER")
    seen: list[float] = []
    done = threading.Event()

    def cb(value):
        seen.append(value)
        if value == 3.0:
            done.set()

    sub = counter.counter.subscribe(cb)
    for _ in range(3):
        counter.increment()
    assert done.wait(5)
    assert seen == [0.0, 1.0, 2.0, 3.0]
    sub.unsubscribe()
    counter.increment()
    counter.state.when("Ready", timeout=5)  # a round trip through the loop
    time.sleep(0.05)
    assert seen == [0.0, 1.0, 2.0, 3.0]


def test_a_callback_may_make_blocking_calls(tp):
    counter = tp.block("COUNTER")
    got = []
    done = threading.Event()

    def cb(value):
        if value == 1.0:
            got.append(tp.block("HELLO").greet(name="cb"))
            done.set()

    with counter.counter.subscribe(cb):
        counter.increment()
        assert done.wait(5)
    assert got == [{"greeting": "Hello cb"}]


def test_delta_subscription_gets_changes(tp):
    changes = []
    done = threading.Event()

    def cb(delta):
        changes.append(delta)
        if len(changes) == 2:
            done.set()

    tp.block("COUNTER").counter.subscribe(cb, delta=True)
    tp.block("COUNTER").counter.put(4)
    assert done.wait(5)
    assert changes[0][0][0] == []
    assert ["value"] in [c[0] for c in changes[1]]


def test_scan_on_scan_block_runs_to_finished(tp):
    scan = tp.block("SCAN")
    scan.configure(generator=demo_generator(2, 3, 0.001), axesToMove=["x"])
    assert scan.state.value == "Armed"
    assert scan.totalSteps.value == 6
    while scan.state.value != "Finished":
        scan.run()
    assert scan.completedSteps.value == 6
    assert tp.block("DET1").state.value == "Finished"
    scan.reset()
    assert scan.state.when("Ready", timeout=5) == "Ready"


def test_scan_on_a_detector(tp):
    det = tp.block("DET1")
    det.configure(generator=demo_generator(1, 4, 0.001))
    det.run()
    det.state.when("Finished", timeout=10)
    assert det.completedSteps.value == 4


def test_abort_from_another_thread_aborts_a_running_scan(tp):
    scan = tp.block("SCAN")
    scan.configure(generator=demo_generator(20, 20, 0.05))
    run = scan.run.future()
    scan.state.when("Running", timeout=5)
    scan.abort()
    with pytest.raises(AbortedError):
        run.result(10)
    assert scan.state.value == "Aborted"


def test_concurrent_calls_from_several_threads(tp):
    hello = tp.block("HELLO")
    counter = tp.block("COUNTER")

    def work(i):
        greeting = hello.greet(name=f"t{i}", sleep=0.01)
        counter.increment()
        return greeting["greeting"]

    with ThreadPoolExecutor(8) as pool:
        results = list(pool.map(work, range(40)))
    assert results == [f"Hello t{i}" for i in range(40)]
    assert counter.counter.value == 40.0


def test_error_method_raises_with_its_message(tp):
    with pytest.raises(RuntimeError, match=r"You called method error\(\)"):
        tp.block("HELLO").error()


def test_malcolm_errors_are_raised_unchanged(tp):
    scan = tp.block("SCAN")
    with pytest.raises(NotAllowedError, match="run"):
        scan.run()  # not configured
    with pytest.raises(BadValueError):
        tp.block("COUNTER").counter.put("lots")
    with pytest.raises(NotFoundError):
        tp.block("NOPE")
    with pytest.raises(AttributeError, match="no field 'nope'"):
        tp.block("HELLO").nope  # noqa: B018
    with pytest.raises(NotFoundError):
        tp.block("HELLO")["nope"]


def test_when_times_out_and_sees_bad_values(tp):
    state = tp.block("HELLO").state
    with pytest.raises(WaitTimeoutError, match="Ready"):
        state.when("Fault", timeout=0.05)
    with pytest.raises(BadValueError, match="Ready"):
        state.when("Fault", bad_values=["Ready"])
    assert state.when(lambda v: v.startswith("Re"), timeout=1) == "Ready"


def test_blocking_call_on_the_loop_thread_is_refused(tp):
    errors = []

    def on_loop():
        try:
            tp.get(["HELLO", "state", "value"])
        except RuntimeError as e:
            errors.append(str(e))

    tp.call_in_loop(on_loop)
    assert errors and "own loop" in errors[0]


def test_context_manager_starts_and_stops():
    with ThreadedProcess(demo_process()) as tp:
        assert tp.block("HELLO").greet(name="cm") == {"greeting": "Hello cm"}
        thread = tp._thread
    assert not tp.started and not thread.is_alive()
    tp.stop()  # twice is fine
    with pytest.raises(RuntimeError, match="not running"):
        tp.get(["HELLO"])


def test_start_twice_is_an_error(tp):
    with pytest.raises(RuntimeError, match="already started"):
        tp.start()


def test_running_on_the_current_loop():
    async def main():
        async with running(demo_process()) as p:
            assert p.get(["HELLO", "state", "value"]) == "Ready"
            return await p.post(["HELLO", "greet"], {"name": "async"})

    assert asyncio.run(main()) == {"greeting": "Hello async"}


def test_from_file(tmp_path):
    pytest.importorskip(
        "malcolm.config.build", reason="build_process (malcolm.config.build) not yet"
    )
    from malcolm.config import registry

    if "parts.HelloPart" not in registry.known_kinds():
        pytest.skip("parts.HelloPart not registered yet")
    blocks = tmp_path / "blocks"
    (blocks / "t").mkdir(parents=True)
    (blocks / "t" / "Hello.yaml").write_text("parts.HelloPart:\n    name: hello\n")
    proc = tmp_path / "proc.yaml"
    proc.write_text("block.t.Hello:\n    mri: T:HELLO\n")
    with ThreadedProcess.from_file(str(proc), [str(blocks)]) as tp:
        assert tp.block("T:HELLO").greet(name="f") == {"greeting": "Hello f"}


def test_metas_and_dicts(tp):
    counter = tp.block("COUNTER")
    assert counter.counter.meta["writeable"] is True
    assert "takes" in tp.block("HELLO").greet.meta
    assert set(counter.to_dict()) >= {"counter", "delta", "increment"}
    assert "counter" in dir(counter)
    assert repr(counter) == "<BlockProxy COUNTER>"


def test_stop_during_a_call_aborts_the_caller():
    tp = start_process(demo_process())
    scan = tp.block("SCAN")
    scan.configure(generator=demo_generator(20, 20, 0.05))
    run = scan.run.future()
    scan.state.when("Running", timeout=5)
    tp.stop(timeout=10)
    with pytest.raises(AbortedError):
        run.result(5)


def test_a_process_that_fails_to_start_leaves_no_thread():
    from malcolm.core import Process

    class Broken(Process):
        async def start(self):
            raise RuntimeError("no hardware")

    tp = ThreadedProcess(Broken("broken"))
    with pytest.raises(RuntimeError, match="no hardware"):
        tp.start()
    assert tp._thread is None and not tp.started
    assert not [t for t in threading.enumerate() if t.name.startswith("malcolm-broken")]

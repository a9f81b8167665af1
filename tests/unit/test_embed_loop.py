"""malcolm.embed.loop: the loop malcolm's own processes run on, and the
choice of it by MALCOLM_LOOP."""

from __future__ import annotations

import asyncio

import pytest
import uvloop

from malcolm.demo import demo_process
from malcolm.embed import start_process
from malcolm.embed.loop import LOOP_ENV, LoopChoiceError, loop_name, new_event_loop, run


def test_by_default_it_is_uvloops_where_installed(monkeypatch) -> None:
    monkeypatch.delenv(LOOP_ENV, raising=False)
    assert loop_name() == "uvloop"
    loop = new_event_loop()
    try:
        assert isinstance(loop, uvloop.Loop)
    finally:
        loop.close()


def test_malcolm_loop_asyncio_chooses_the_standard_librarys(monkeypatch) -> None:
    monkeypatch.setenv(LOOP_ENV, "asyncio")
    assert loop_name() == "asyncio"
    loop = new_event_loop()
    try:
        assert not isinstance(loop, uvloop.Loop)
        assert isinstance(loop, asyncio.BaseEventLoop)
    finally:
        loop.close()


def test_an_unknown_choice_is_refused_naming_it(monkeypatch) -> None:
    monkeypatch.setenv(LOOP_ENV, "trio")
    with pytest.raises(LoopChoiceError, match="MALCOLM_LOOP='trio': expected"):
        new_event_loop()


def test_uvloop_required_but_missing_says_how_to_mend_it(monkeypatch) -> None:
    import malcolm.embed.loop as module

    monkeypatch.setenv(LOOP_ENV, "uvloop")
    monkeypatch.setattr(module, "_uvloop_factory", lambda: None)
    with pytest.raises(LoopChoiceError, match="uvloop is not installed"):
        loop_name()
    monkeypatch.delenv(LOOP_ENV)
    assert loop_name() == "asyncio"  # unset: asyncio's, without complaint


@pytest.mark.parametrize("choice", ["uvloop", "asyncio"])
def test_run_runs_a_coroutine_on_the_chosen_loop(monkeypatch, choice: str) -> None:
    monkeypatch.setenv(LOOP_ENV, choice)

    async def which() -> bool:
        return isinstance(asyncio.get_running_loop(), uvloop.Loop)

    assert run(which()) is (choice == "uvloop")


@pytest.mark.parametrize("choice", ["uvloop", "asyncio"])
def test_a_threaded_demo_process_works_on_either_loop(monkeypatch, choice) -> None:
    monkeypatch.setenv(LOOP_ENV, choice)
    with start_process(demo_process()) as tp:
        assert isinstance(tp.loop, uvloop.Loop) is (choice == "uvloop")
        hello = tp.block("HELLO")
        assert hello.greet(name="me") == {"greeting": "Hello me"}
        counter = tp.block("COUNTER")
        counter.counter.put(3)
        counter.increment()
        assert counter.counter.value == 4.0

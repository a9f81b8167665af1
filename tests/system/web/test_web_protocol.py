"""The JSON protocol of interop.md §3 over a real WebSocket, against the demo."""

from __future__ import annotations

import asyncio
import json

import aiohttp

from malcolm.core import apply_changes
from malcolm.demo import demo_generator

from .conftest import (
    DELTA,
    ERROR,
    GET,
    POST,
    PUT,
    RETURN,
    SUBSCRIBE,
    UNSUBSCRIBE,
    UPDATE,
    connect,
    run,
)


def test_get_put_post_return_and_error(served):
    async def body():
        async with aiohttp.ClientSession() as s:
            c = await connect(s, served)
            blocks = await c.value(GET, path=[".", "blocks", "value"])
            assert blocks == served.call(lambda: served.process.mris)
            block = await c.value(GET, path=["COUNTER"])
            assert block == served.get(["COUNTER"])
            assert block["typeid"] == "malcolm:core/Block:1.0"
            reply = await c.request(PUT, path=["COUNTER", "counter", "value"], value=5)
            assert reply == {"typeid": RETURN, "id": reply["id"], "value": None}
            assert served.get(["COUNTER", "counter", "value"]) == 5
            await c.value(PUT, path=["COUNTER", "counter"], value=6)
            assert await c.value(GET, path=["COUNTER", "counter", "value"]) == 6
            greeting = await c.value(
                POST, path=["HELLO", "greet"], parameters={"name": "web"}
            )
            assert greeting == {"greeting": "Hello web"}
            assert await c.value(POST, path=["COUNTER", "increment"]) is None
            assert served.get(["COUNTER", "counter", "value"]) == 7
            err = await c.request(POST, id=77, path=["HELLO", "error"])
            assert err["typeid"] == ERROR and err["id"] == 77
            assert err["message"].split(":")[0].endswith("Error")
            err = await c.request(PUT, path=["COUNTER", "counter"], value="x")
            assert err["typeid"] == ERROR
            assert err["message"].startswith("BadValueError: COUNTER.counter")
            assert served.get(["COUNTER", "counter", "value"]) == 7
            err = await c.request(POST, path=["SCAN", "run"])
            assert err["message"].startswith("NotAllowedError: SCAN: run()")

    run(body())


def test_subscribe_update_delta_and_unsubscribe(served):
    async def body():
        async with aiohttp.ClientSession() as s:
            c = await connect(s, served)
            await c.send(
                {"typeid": SUBSCRIBE, "id": 1, "path": ["COUNTER", "counter", "value"]}
            )
            first = await c.wait_for(1, (UPDATE,))
            assert first == {"typeid": UPDATE, "id": 1, "value": 0}
            await c.send(
                {
                    "typeid": SUBSCRIBE,
                    "id": 2,
                    "path": ["COUNTER", "counter"],
                    "delta": True,
                }
            )
            first = await c.wait_for(2, (DELTA,))
            assert first["changes"] == [[[], served.get(["COUNTER", "counter"])]]
            await c.value(PUT, id=3, path=["COUNTER", "counter"], value=4)
            assert (await c.wait_for(1, (UPDATE,)))["value"] == 4
            changes = (await c.wait_for(2, (DELTA,)))["changes"]
            assert [["value"], 4] in changes
            assert all(len(ch) in (1, 2) and isinstance(ch[0], list) for ch in changes)
            # a duplicate subscription id is an error; the first one goes on
            dup = await c.request(SUBSCRIBE, id=1, path=["HELLO"])
            assert dup["typeid"] == ERROR and "1 is in use" in dup["message"]
            assert await c.value(UNSUBSCRIBE, id=1) is None
            await c.value(PUT, id=4, path=["COUNTER", "counter"], value=9)
            assert (await c.wait_for(2, (DELTA,)))["changes"][0] == [["value"], 9]
            assert c.take(1) == []  # nothing more for the ended subscription
            again = await c.request(UNSUBSCRIBE, id=1)
            assert again["typeid"] == ERROR and "no subscription" in again["message"]
            # the block list and a model are served under "."
            await c.send(
                {"typeid": SUBSCRIBE, "id": 5, "path": [".", "blocks", "value"]}
            )
            assert "SCAN" in (await c.wait_for(5, (UPDATE,)))["value"]
            model = await c.value(GET, path=[".", "models", "SCAN"])
            names = [st["name"] for st in model["states"]]
            for state in ("Configuring", "Armed", "Running", "Finished"):
                assert state in names
            assert "Armed" in model["methods"]["run"]
            assert any(
                t["source"] == "Armed" and t["dest"] == "Running"
                for t in model["transitions"]
            )

    run(body())


async def _scan(c, generator=None):
    params = {"generator": generator or demo_generator(duration=0.01)}
    await c.value(POST, path=["SCAN", "configure"], parameters=params)
    while (await c.value(GET, path=["SCAN", "state", "value"])) != "Finished":
        await c.value(POST, path=["SCAN", "run"])


def test_deltas_rebuild_what_a_fresh_get_returns_after_a_scan(served):
    async def body():
        async with aiohttp.ClientSession() as s:
            c = await connect(s, served)
            paths = [["SCAN"], ["DET1"], ["MOTOR:X"], ["SCAN", "completedSteps"]]
            for i, path in enumerate(paths, start=100):
                await c.send(
                    {"typeid": SUBSCRIBE, "id": i, "path": path, "delta": True}
                )
            await _scan(c)
            await c.value(PUT, path=["MOTOR:X", "demand"], value=1.5)
            copies = {}
            for i, path in enumerate(paths, start=100):
                fresh = await c.value(GET, path=path)  # after every delta before it
                deltas = c.take(i)
                assert len(deltas) > 2 and all(d["typeid"] == DELTA for d in deltas)
                data = None
                for d in deltas:
                    data = apply_changes(data, d["changes"])
                copies[i] = data
                assert data == fresh, path
            assert copies[100]["state"]["value"] == "Finished"
            assert copies[103]["value"] == 12

    run(body())


def test_many_subscriptions_on_one_connection(served):
    async def body():
        async with aiohttp.ClientSession() as s:
            c = await connect(s, served)
            mris = await c.value(GET, path=[".", "blocks", "value"])
            ids = {}
            for mri in mris:
                for field in served.get([mri, "meta", "fields"]):
                    ids[len(ids) + 1] = [mri, field]
            for id_, path in ids.items():
                await c.send({"typeid": SUBSCRIBE, "id": id_, "path": path})
            assert len(ids) > 80
            for id_ in ids:
                await c.wait_for(id_, (UPDATE,))
            counter = next(i for i, p in ids.items() if p == ["COUNTER", "counter"])
            demand = next(i for i, p in ids.items() if p == ["MOTOR:Y", "demand"])
            await c.value(PUT, path=["COUNTER", "counter"], value=3)
            await c.value(PUT, path=["MOTOR:Y", "demand"], value=2.0)
            assert (await c.wait_for(counter, (UPDATE,)))["value"]["value"] == 3
            assert (await c.wait_for(demand, (UPDATE,)))["value"]["value"] == 2.0

    run(body())


def test_fifty_clients_during_a_scan_all_end_with_the_final_values(served):
    async def body():
        async with aiohttp.ClientSession() as s:
            clients = [await connect(s, served) for _ in range(50)]
            for c in clients:
                await c.send(
                    {
                        "typeid": SUBSCRIBE,
                        "id": 1,
                        "path": ["SCAN", "completedSteps", "value"],
                    }
                )
                await c.send(
                    {"typeid": SUBSCRIBE, "id": 2, "path": ["SCAN", "state", "value"]}
                )
                await c.send(
                    {"typeid": SUBSCRIBE, "id": 3, "path": ["SCAN"], "delta": True}
                )
            await _scan(clients[0], demo_generator(ny=3, nx=5, duration=0.01))
            final = await clients[0].value(GET, path=["SCAN"])
            for c in clients:
                await c.value(GET, id=99, path=["HELLO", "state"])  # a barrier
                steps = [m["value"] for m in c.take(1)]
                states = [m["value"] for m in c.take(2)]
                data = None
                for m in c.take(3):
                    data = apply_changes(data, m["changes"])
                assert steps[-1] == 15 and steps == sorted(steps)
                assert states[-1] == "Finished"
                for state in ("Configuring", "Armed", "Running"):
                    assert state in states
                assert data == final

    run(body())


def test_malformed_input_is_answered_with_error_and_changes_nothing(served):
    async def body():
        async with aiohttp.ClientSession() as s:
            c = await connect(s, served)
            before = {
                m: served.get([m]) for m in served.call(lambda: served.process.mris)
            }
            bad: list[tuple[str | dict, int, str]] = [
                ("{not json", -1, "malformed JSON"),
                ("[1, 2]", -1, "a message is a JSON object"),
                ('"text"', -1, "a message is a JSON object"),
                ({"typeid": GET, "path": ["HELLO"]}, -1, "'id' must be an integer"),
                ({"typeid": GET, "id": "7", "path": ["HELLO"]}, -1, "'id' must be"),
                ({"typeid": GET, "id": 1.5, "path": ["HELLO"]}, -1, "'id' must be"),
                ({"typeid": "malcolm:core/Nope:1.0", "id": 3}, 3, "unknown typeid"),
                ({"id": 4, "path": ["HELLO"]}, 4, "unknown typeid"),
                ({"typeid": GET, "id": 5}, 5, "needs 'path'"),
                ({"typeid": GET, "id": 6, "path": "HELLO"}, 6, "'path' must be"),
                ({"typeid": GET, "id": 7, "path": []}, 7, "'path' must be"),
                ({"typeid": GET, "id": 8, "path": ["HELLO", 1]}, 8, "'path' must be"),
                (
                    {"typeid": PUT, "id": 9, "path": ["COUNTER", "counter"]},
                    9,
                    "needs 'value'",
                ),
                (
                    {
                        "typeid": POST,
                        "id": 10,
                        "path": ["HELLO", "greet"],
                        "parameters": [1],
                    },
                    10,
                    "'parameters' must be an object",
                ),
                (
                    {"typeid": SUBSCRIBE, "id": 11, "path": ["HELLO"], "delta": "yes"},
                    11,
                    "'delta' must be true or false",
                ),
                ({"typeid": GET, "id": 12, "path": ["NOPE"]}, 12, "no block 'NOPE'"),
                ({"typeid": GET, "id": 13, "path": ["HELLO", "nope"]}, 13, "nope"),
                ({"typeid": GET, "id": 14, "path": [".", "nope"]}, 14, "under '.'"),
                ({"typeid": SUBSCRIBE, "id": 15, "path": ["NOPE", "x"]}, 15, "NOPE"),
                (
                    {
                        "typeid": PUT,
                        "id": 16,
                        "path": ["COUNTER", "counter"],
                        "value": [1],
                    },
                    16,
                    "BadValueError",
                ),
                (
                    {
                        "typeid": PUT,
                        "id": 17,
                        "path": ["COUNTER", "state"],
                        "value": "Fault",
                    },
                    17,
                    "Error",
                ),
                (
                    {
                        "typeid": POST,
                        "id": 18,
                        "path": ["HELLO", "greet"],
                        "parameters": {"x": 1},
                    },
                    18,
                    "HELLO.greet.x",
                ),
                ({"typeid": PUT, "id": 19, "path": ["HELLO"], "value": 1}, 19, "Error"),
                (
                    {"typeid": GET, "id": 20, "path": ["HELLO"], "extra": 1},
                    20,
                    "'extra'",
                ),
                ("x" * (2 << 20), -1, "over the limit"),
                (
                    json.dumps({"typeid": GET, "id": 21, "path": ["x" * (2 << 20)]}),
                    -1,
                    "limit",
                ),
            ]
            for message, id_, text in bad:
                await c.send(message)
                reply = await c.wait_for(id_, (ERROR, RETURN, UPDATE, DELTA))
                assert reply["typeid"] == ERROR, (message, reply)
                assert text in reply["message"], (str(message)[:100], reply)
                assert "Traceback" not in reply["message"]
            # the connection is still up and nothing changed
            assert await c.value(GET, path=["HELLO", "state", "value"]) == "Ready"
            after = {m: served.get([m]) for m in before}
            assert after == before
            assert c.inbox == []

    run(body())


def test_a_client_that_goes_mid_run_does_not_stop_the_scan(served):
    async def body():
        async with aiohttp.ClientSession() as s:
            c = await connect(s, served)
            params = {"generator": demo_generator(ny=2, nx=3, duration=0.05)}
            await c.value(POST, path=["SCAN", "configure"], parameters=params)
            await c.send({"typeid": POST, "id": 50, "path": ["SCAN", "run"]})
            other = await connect(s, served)
            await other.send(
                {"typeid": SUBSCRIBE, "id": 1, "path": ["SCAN", "state", "value"]}
            )
            assert (await other.wait_for(1, (UPDATE,)))["value"] in ("Armed", "Running")
            await c.ws.close()  # gone mid-run
            state = None
            while state != "Finished":
                state = (await other.wait_for(1, (UPDATE,)))["value"]
                assert state in ("Running", "PostRun", "Finished"), state
            assert served.get(["SCAN", "completedSteps", "value"]) == 6

    run(body())


def test_a_client_that_does_not_read_is_dropped_and_others_go_on(served, monkeypatch):
    from malcolm.io.web import session

    monkeypatch.setattr(session, "MAX_QUEUED", 20)

    async def body():
        async with aiohttp.ClientSession() as s:
            stuck = await connect(s, served)
            fine = await connect(s, served)
            for i in range(10):  # some 30 kB per put that it never reads
                await stuck.send(
                    {"typeid": SUBSCRIBE, "id": i, "path": ["COUNTER"], "delta": False}
                )
            await fine.send(
                {"typeid": SUBSCRIBE, "id": 1, "path": ["COUNTER", "counter", "value"]}
            )
            await fine.wait_for(1, (UPDATE,))

            async def many_puts():
                for i in range(3000):
                    await served.process.put(["COUNTER", "counter"], i)
                    await asyncio.sleep(0)  # as puts from clients arrive

            served.call(many_puts, timeout=120)
            assert (await fine.value(GET, path=["COUNTER", "counter", "value"])) == 2999
            # the stuck client is closed by the server once it reads again
            while True:
                msg = await stuck.ws.receive(20)
                if msg.type != aiohttp.WSMsgType.TEXT:
                    break
            assert msg.type in (aiohttp.WSMsgType.CLOSE, aiohttp.WSMsgType.CLOSED)
            assert stuck.ws.close_code == 1008

    run(body())


def _add_counter(served, mri: str) -> None:
    from malcolm.controllers.stateful import StatefulController
    from malcolm.parts.demo import CounterPart

    controller = StatefulController(mri, [CounterPart("counter")])

    async def add() -> None:
        served.process.add_controller(controller)
        await controller.start()

    served.call(add)


def _remove(served, mri: str) -> None:
    async def remove() -> None:
        await served.process.get_controller(mri).stop()
        served.process.remove_controller(mri)

    served.call(remove)


def test_the_block_list_follows_blocks_added_and_removed(served):
    async def body():
        async with aiohttp.ClientSession() as s:
            c = await connect(s, served)
            await c.send({"typeid": SUBSCRIBE, "id": 3, "path": [".", "blocks"]})
            first = (await c.wait_for(3, (UPDATE,)))["value"]
            assert first["value"] == served.call(lambda: served.process.mris)
            await c.send(
                {
                    "typeid": SUBSCRIBE,
                    "id": 4,
                    "path": [".", "blocks", "value"],
                    "delta": True,
                }
            )
            assert "LATE" not in (await c.wait_for(4, (DELTA,)))["changes"][0][1]
            _add_counter(served, "LATE")
            assert (await c.wait_for(3, (UPDATE,)))["value"]["value"][-1] == "LATE"
            changes = (await c.wait_for(4, (DELTA,)))["changes"]
            assert changes == [[[], served.call(lambda: served.process.mris)]]
            # the model of a block added late is served too
            model = await c.value(GET, path=[".", "models", "LATE"])
            assert model["typeid"] == "malcolm:fsm/Model:1.0"
            await c.value(UNSUBSCRIBE, id=4)
            await c.send(
                {"typeid": SUBSCRIBE, "id": 6, "path": [".", "models", "LATE"]}
            )
            assert (await c.wait_for(6, (UPDATE,)))["value"] == model
            _remove(served, "LATE")
            ended = await c.wait_for(6, (ERROR,))
            assert ended["message"].startswith("NotFoundError: ")
            assert "LATE" in ended["message"]
            gone = (await c.wait_for(3, (UPDATE,)))["value"]["value"]
            assert "LATE" not in gone and "COUNTER" in gone
            # a round trip after the removal: anything sent for id 4 is kept
            assert await c.value(GET, path=["COUNTER", "counter", "value"]) == 0
            # nothing for the ended subscription
            assert [m for m in c.take(4) if m.get("typeid") == DELTA] == []

    run(body())

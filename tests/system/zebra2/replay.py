"""A small scripted control-port server for the client's tests.

It answers from the recorded tier-2 introspection (``raw``: every command
the recording sent, with the reply lines it got), keeps the values that
``*CHANGES?`` reported at start, takes writes (checking enum labels,
bounded uints and table row widths with the recorded error texts), and
reports changes per connection as the recorded server does (the first
``*CHANGES?`` of a connection gives every value). It is not the simulator
(``malcolm.sim.zebra2``): only what these tests need.
"""

from __future__ import annotations

import asyncio
import json
from pathlib import Path

SHARED = Path(__file__).resolve().parents[3].parent / "shared" / "zebra2"
TIER2 = SHARED / "introspection-tier2.json"


class ReplayServer:
    def __init__(self, path: Path = TIER2) -> None:
        data = json.loads(path.read_text())
        self.raw: dict[str, list[str]] = {
            k: v for k, v in data["raw"].items() if "  #" not in k
        }
        self.details = data["block_details"]
        self.values: dict[str, str] = {}
        self.order: list[str] = []
        for line in data["changes_initial"]["*CHANGES?"]:
            if line == ".":
                continue
            text = line[1:]
            if text.endswith("<"):
                name, value = text[:-1], None
            else:
                name, _, value = text.partition("=")
            self.order.append(name)
            self.values[name] = value
        self.tables: dict[str, list[str]] = {}
        self.connections: list[set[str] | None] = []
        self.server: asyncio.base_events.Server | None = None
        self.writers: list[asyncio.StreamWriter] = []
        self.handlers: set[asyncio.Task] = set()
        self.received: list[str] = []

    async def start(self, host: str = "127.0.0.1", port: int = 0) -> int:
        self.server = await asyncio.start_server(self._serve, host, port)
        return self.server.sockets[0].getsockname()[1]

    async def close(self) -> None:
        if self.server is not None:
            self.server.close()
        self.drop_clients()
        if self.server is not None:
            await self.server.wait_closed()

    def drop_clients(self) -> None:
        for w in self.writers:
            w.close()
        self.writers = []
        for task in self.handlers:
            task.cancel()

    # ---- the protocol
    def _field(self, name: str) -> dict | None:
        block, _, rest = name.partition(".")
        field = rest.split(".")[0]
        base = block.rstrip("0123456789")
        for f in self.details.get(base, {}).get("fields", []):
            if f["name"] == field:
                return f
        return None

    def _set(self, name: str, value: str | None) -> None:
        if name not in self.values:
            self.order.append(name)
        self.values[name] = value
        for changed in self.connections:
            if changed is not None:
                changed.add(name)

    def write(self, name: str, value: str) -> str:
        """A write (as a client would make it): the reply line."""
        key = self._key(name)
        f = self._field(name)
        if key is None or f is None:
            return "ERR No such field"
        labels = (f.get("enums") or {}).get("values")
        parts = name.split(".")
        if len(parts) == 2 and labels and value not in labels:
            return "ERR Invalid enumeration value"
        if len(parts) == 2 and f["subtype"] == "uint":
            maximum = f["attributes"]["MAX"]["value_instance1"]["value"]
            try:
                number = int(value, 0)
            except ValueError:
                return "ERR Number missing"
            if number > int(maximum):
                return "ERR Number out of range"
        if len(parts) == 2 and f["type"] in ("bit_out", "pos_out", "read"):
            return "ERR Field not writeable"
        self._set(key, value)
        return "OK"

    def _key(self, name: str) -> str | None:
        if name in self.values:
            return name
        block, _, rest = name.partition(".")
        if block.endswith("1") and f"{block[:-1]}.{rest}" in self.values:
            return f"{block[:-1]}.{rest}"
        return None

    def _answer(self, line: str, conn: int) -> list[str]:
        if line == "*CHANGES?":
            changed = self.connections[conn]
            names = (
                self.order
                if changed is None
                else [n for n in self.order if n in changed]
            )
            self.connections[conn] = set()
            out = []
            for n in names:
                v = self.values[n]
                out.append(f"!{n}<" if v is None else f"!{n}={v}")
            return [*out, "."]
        if line.endswith("?"):
            key = self._key(line[:-1])
            if key is not None and self.values[key] is not None:
                return [f"OK ={self.values[key]}"]
            if key is not None:
                return [f"!{w}" for w in self.tables.get(key, [])] + ["."]
            if line in self.raw:
                return self.raw[line]
            block, _, rest = line.partition(".")
            if f"{block}1.{rest}" in self.raw:  # a single-instance block
                return self.raw[f"{block}1.{rest}"]
            return ["ERR No such field"]
        if "=" in line:
            name, _, value = line.partition("=")
            if name.startswith("*"):
                return ["OK"]
            return [self.write(name, value)]
        return ["ERR Unknown command"]

    async def _serve(self, reader, writer) -> None:
        task = asyncio.current_task()
        self.handlers.add(task)
        task.add_done_callback(self.handlers.discard)
        self.writers.append(writer)
        conn = len(self.connections)
        self.connections.append(None)
        try:
            while True:
                raw = await reader.readline()
                if not raw:
                    break
                line = raw.decode().rstrip("\n")
                self.received.append(line)
                if "<" in line:
                    name = line.partition("<")[0]
                    words = []
                    while (row := (await reader.readline()).decode().strip()) != "":
                        words += row.split()
                    f = self._field(name)
                    row_words = 4
                    if f is not None and "ROW_WORDS" in f.get("attributes", {}):
                        attr = f["attributes"]["ROW_WORDS"]["value_instance1"]
                        row_words = int(attr["value"])
                    key = self._key(name)
                    if key is None:
                        reply = ["ERR No such field"]
                    elif len(words) % row_words:
                        reply = ["ERR Table write is not a whole number of rows"]
                    else:
                        self.tables[key] = words
                        self._set(key, None)
                        reply = ["OK"]
                else:
                    reply = self._answer(line, conn)
                writer.write("".join(r + "\n" for r in reply).encode())
                await writer.drain()
        except (ConnectionError, asyncio.IncompleteReadError):
            pass
        except asyncio.CancelledError:
            return  # dropped by the test
        finally:
            writer.close()

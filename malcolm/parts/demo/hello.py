"""HelloPart: greet(name, sleep) and error(), to try calls out."""

from __future__ import annotations

import asyncio

from malcolm.core import MapMeta, StringMeta

from ..base import Part, PartRegistrar


class HelloPart(Part):
    """Adds ``greet(name, sleep=0)`` returning a greeting, and ``error()``."""

    def setup(self, registrar: PartRegistrar) -> None:
        registrar.add_method(
            self.greet,
            returns=MapMeta({"greeting": StringMeta("The greeting")}, ["greeting"]),
        )
        registrar.add_method(self.error)

    async def greet(self, name: str, sleep: float = 0.0) -> dict[str, str]:
        """Say hello to name after sleeping for sleep seconds."""
        if sleep > 0:
            await asyncio.sleep(sleep)
        return {"greeting": f"Hello {name}"}

    def error(self) -> None:
        """Raise an error, to see how one is reported."""
        raise RuntimeError("You called method error()")

"""The web side: the JSON protocol over WebSocket, a REST face and the web GUI.

``await start_web_server(process, port)`` serves a started process; see
docs/web.md. aiohttp is imported on first use (``malcolm.io.web.cli`` does
not need it), so a process that serves no web pays nothing for it.
"""

from __future__ import annotations

from typing import Any

__all__ = ["WebServer", "model_data", "start_web_server"]


def __getattr__(name: str) -> Any:
    if name in ("WebServer", "start_web_server"):
        from . import server

        return getattr(server, name)
    if name == "model_data":
        from .directory import model_data

        return model_data
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

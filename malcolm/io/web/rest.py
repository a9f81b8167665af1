"""The REST face: ``GET /rest/<mri>[/<field>...]``, ``PUT /rest/<mri>/<attr>``
with a JSON value, ``POST /rest/<mri>/<method>`` with JSON arguments.

Errors are HTTP statuses with the message as JSON ``{"error": "<Type>: <text>"}``:
400 bad JSON or value, 403 not writeable, 404 not found, 409 not allowed in
this state or aborted, 413 too large, 500 anything else.
"""

from __future__ import annotations

import json
import logging
from typing import Any

from aiohttp import web

from malcolm.core import (
    AbortedError,
    BadValueError,
    MalcolmError,
    NotAllowedError,
    NotFoundError,
    NotWriteableError,
    Process,
)

from . import protocol as p
from .directory import directory_get

log = logging.getLogger(__name__)

STATUS: list[tuple[type[BaseException], int]] = [
    (BadValueError, 400),
    (NotWriteableError, 403),
    (NotFoundError, 404),
    (NotAllowedError, 409),
    (AbortedError, 409),
]


def _json(value: Any, status: int = 200) -> web.Response:
    return web.Response(
        text=p.dumps(value), status=status, content_type="application/json"
    )


def _failure(e: BaseException) -> web.Response:
    status = next((s for t, s in STATUS if isinstance(e, t)), 500)
    return _json({"error": p.error_text(e)}, status)


def _path(request: web.Request) -> list[str]:
    return [part for part in request.match_info["path"].split("/") if part]


async def _body(request: web.Request) -> Any:
    if request.content_length is not None and request.content_length > p.MAX_MESSAGE:
        raise _TooLarge(f"body of {request.content_length} bytes is over the limit")
    text = await request.text()
    if not text.strip():
        return None
    try:
        return json.loads(text)
    except ValueError as e:
        raise BadValueError(f"malformed JSON: {e}") from None


class _TooLarge(MalcolmError):
    pass


def add_rest_routes(app: web.Application, process: Process) -> None:
    """Add the ``/rest/`` routes serving ``process`` to ``app``."""

    async def get(request: web.Request) -> web.Response:
        path = _path(request)
        try:
            if not path:
                return _json(list(process.mris))
            if path[0] == ".":
                return _json(directory_get(process, path))
            return _json(process.get(path))
        except MalcolmError as e:
            return _failure(e)

    async def put(request: web.Request) -> web.Response:
        path = _path(request)
        try:
            if len(path) != 2:
                raise NotFoundError(f"PUT needs /rest/<mri>/<attribute>, got {path}")
            value = await _body(request)
            await process.put(path, value)
            return _json(process.get([*path, "value"]))
        except _TooLarge as e:
            return _json({"error": p.error_text(e)}, 413)
        except MalcolmError as e:
            return _failure(e)
        except Exception as e:  # a part's bug: the caller hears of it
            log.warning("REST PUT %s failed", path, exc_info=True)
            return _failure(e)

    async def post(request: web.Request) -> web.Response:
        path = _path(request)
        try:
            if len(path) != 2:
                raise NotFoundError(f"POST needs /rest/<mri>/<method>, got {path}")
            params = await _body(request)
            if params is None:
                params = {}
            if not isinstance(params, dict):
                raise BadValueError(
                    f"the arguments are a JSON object, got {type(params).__name__}"
                )
            return _json(await process.post(path, params))
        except _TooLarge as e:
            return _json({"error": p.error_text(e)}, 413)
        except MalcolmError as e:
            return _failure(e)
        except Exception as e:
            log.warning("REST POST %s failed", path, exc_info=True)
            return _failure(e)

    app.router.add_get("/rest/{path:.*}", get)
    app.router.add_put("/rest/{path:.*}", put)
    app.router.add_post("/rest/{path:.*}", post)

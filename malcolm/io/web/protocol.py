"""The JSON messages of the web protocol (interop.md §3): parsing and encoding.

Client to server: ``malcolm:core/Get:1.0`` {id, path}, ``Put:1.0`` {id, path,
value}, ``Post:1.0`` {id, path, parameters}, ``Subscribe:1.0`` {id, path,
delta}, ``Unsubscribe:1.0`` {id}. Server to client: ``Return:1.0`` {id,
value}, ``Error:1.0`` {id, message}, ``Update:1.0`` {id, value},
``Delta:1.0`` {id, changes}.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any

from malcolm.core import BadValueError

GET = "malcolm:core/Get:1.0"
PUT = "malcolm:core/Put:1.0"
POST = "malcolm:core/Post:1.0"
SUBSCRIBE = "malcolm:core/Subscribe:1.0"
UNSUBSCRIBE = "malcolm:core/Unsubscribe:1.0"
RETURN = "malcolm:core/Return:1.0"
ERROR = "malcolm:core/Error:1.0"
UPDATE = "malcolm:core/Update:1.0"
DELTA = "malcolm:core/Delta:1.0"

#: the fields each request type takes besides typeid and id (required, optional)
FIELDS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    GET: (("path",), ()),
    PUT: (("path", "value"), ()),
    POST: (("path",), ("parameters",)),
    SUBSCRIBE: (("path",), ("delta",)),
    UNSUBSCRIBE: ((), ()),
}

#: the id of an Error answering a message whose id could not be read
NO_ID = -1

#: the largest message (in characters) a server reads
MAX_MESSAGE = 1 << 20


@dataclass
class Request:
    """One parsed client message."""

    typeid: str
    id: int
    path: list[str]
    value: Any = None
    parameters: dict[str, Any] | None = None
    delta: bool = False


class ProtocolError(BadValueError):
    """A message the protocol refuses; ``id`` is the one to answer (or -1)."""

    def __init__(self, message: str, id: int = NO_ID) -> None:
        super().__init__(message)
        self.id = id


def parse(text: str | bytes) -> Request:
    """Parse and check one client message, raising :class:`ProtocolError`."""
    if len(text) > MAX_MESSAGE:
        raise ProtocolError(
            f"message of {len(text)} characters is over the limit of {MAX_MESSAGE}"
        )
    try:
        msg = json.loads(text)
    except (ValueError, UnicodeDecodeError) as e:
        raise ProtocolError(f"malformed JSON: {e}") from None
    if not isinstance(msg, dict):
        raise ProtocolError(f"a message is a JSON object, got {type(msg).__name__}")
    id_ = msg.get("id")
    if type(id_) is not int:
        raise ProtocolError(f"'id' must be an integer, got {id_!r}"[:200])
    typeid = msg.get("typeid")
    if typeid not in FIELDS:
        known = ", ".join(FIELDS)
        raise ProtocolError(f"unknown typeid {typeid!r} (known: {known})"[:400], id_)
    required, optional = FIELDS[typeid]
    for key in required:
        if key not in msg:
            raise ProtocolError(f"{_short(typeid)} needs {key!r}", id_)
    extra = set(msg) - {"typeid", "id", *required, *optional}
    if extra:
        raise ProtocolError(
            f"{_short(typeid)} takes no {', '.join(map(repr, sorted(extra)))}", id_
        )
    request = Request(typeid, id_, [])
    if "path" in msg:
        path = msg["path"]
        if (
            not isinstance(path, list)
            or not path
            or not all(isinstance(p, str) for p in path)
        ):
            raise ProtocolError(
                f"'path' must be a non-empty list of strings, got {path!r}"[:200], id_
            )
        request.path = path
    if typeid == PUT:
        request.value = msg["value"]
    if typeid == POST:
        params = msg.get("parameters")
        if params is None:
            params = {}
        if not isinstance(params, dict):
            raise ProtocolError(
                f"'parameters' must be an object, got {type(params).__name__}", id_
            )
        request.parameters = params
    if typeid == SUBSCRIBE:
        delta = msg.get("delta", False)
        if not isinstance(delta, bool):
            raise ProtocolError(f"'delta' must be true or false, got {delta!r}", id_)
        request.delta = delta
    return request


def _short(typeid: str) -> str:
    return typeid.rsplit("/", 1)[-1].split(":")[0]


def _plain(obj: Any) -> Any:
    """JSON for what ``json`` does not know: fields, numpy values, sets."""
    to_dict = getattr(obj, "to_dict", None)
    if callable(to_dict):
        return to_dict()
    tolist = getattr(obj, "tolist", None)  # numpy arrays and scalars
    if callable(tolist):
        return tolist()
    if isinstance(obj, set | frozenset):
        return sorted(obj)
    raise TypeError(f"{type(obj).__name__} is not JSON")


def _finite(obj: Any) -> Any:
    """``obj`` with NaN and infinities as None (JSON has neither)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_finite(v) for v in obj]
    return obj


def dumps(message: dict[str, Any]) -> str:
    """``message`` as compact JSON text."""
    try:
        return json.dumps(message, default=_plain, allow_nan=False)
    except ValueError:  # a NaN or infinity somewhere: sent as null
        return json.dumps(_finite(json.loads(json.dumps(message, default=_plain))))


def error_text(e: BaseException) -> str:
    """``"<ExceptionType>: <message>"``, as pvAccess errors read."""
    return f"{type(e).__name__}: {e}"


def return_(id: int, value: Any = None) -> str:
    return dumps({"typeid": RETURN, "id": id, "value": value})


def error(id: int, message: str) -> str:
    return dumps({"typeid": ERROR, "id": id, "message": message})


def update(id: int, value: Any) -> str:
    return dumps({"typeid": UPDATE, "id": id, "value": value})


def delta(id: int, changes: Any) -> str:
    return dumps({"typeid": DELTA, "id": id, "changes": changes})

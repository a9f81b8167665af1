"""EPICS's own console messages (libCom's errlog) go to Python logging.

p4p's C++ libraries write some messages straight to stderr through libCom's
errlog, e.g. ``osiLocalAddr(): only loopback found`` on a machine (or test
namespace) with no network interface but loopback. :func:`route_errlog`
turns errlog's console output off and hands each message to the logger
``malcolm.io.pva.epics`` instead (that one at DEBUG, others at WARNING), so
nothing but malcolm's own lines reach a user's terminal.
"""

from __future__ import annotations

import ctypes
import logging
import threading

log = logging.getLogger("malcolm.io.pva.epics")

_QUIET = ("osiLocalAddr(): only loopback found",)
_LISTENER = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_char_p)
_lock = threading.Lock()
_installed: list[object] = []  # keeps the callback alive


def _on_message(_private: int | None, message: bytes | None) -> None:
    text = (message or b"").decode(errors="replace").strip()
    if text:
        quiet = any(text.startswith(q) for q in _QUIET)
        log.log(logging.DEBUG if quiet else logging.WARNING, "%s", text)


def route_errlog() -> bool:
    """Send libCom's errlog to Python logging (once per process); False if
    libCom cannot be loaded (the messages then stay on stderr)."""
    with _lock:
        if _installed:
            return True
        try:
            from epicscorelibs.path import get_lib

            com = ctypes.CDLL(get_lib("Com"))
            callback = _LISTENER(_on_message)
            com.errlogAddListener(callback, None)
            com.eltc(0)
        except (ImportError, OSError, AttributeError) as e:
            log.debug("errlog stays on stderr: %s", e)
            return False
        _installed.append(callback)
        return True

"""A p4p thread-client monitor without ``Context.monitor``'s start-up race.

``p4p.client.thread.Context.monitor`` (p4p 4.3) makes the raw subscription,
then stores it in the Subscription's ``_S``. Its first wake-up can come, from
a pvxs thread, before it is stored: ``Subscription._event`` then fails its
``assert self._S is not None``, logs "Lost Subscription update" and drops the
wake-up. pvxs wakes a subscription only when its queue goes from empty to not
empty, and nothing empties it, so that monitor never gives a value (seen
under load in test_pva_load: a client held 6 of its 7 blocks for 120 s while
a new client got the 7th at once). The tests' monitors use :func:`monitor`,
which keeps a wake-up that comes early and gives it once the subscription is
stored. It is the client library's race, not the server's: malcolm's own
pvAccess client (``malcolm.io.pva.client_channel``) drains on the loop after
its subscription is stored.
"""

from __future__ import annotations

import threading
from typing import Any

from p4p.client import raw
from p4p.client.thread import Context, Subscription

__all__ = ["StartedSubscription", "monitor"]


class StartedSubscription(Subscription):
    """p4p's thread Subscription, keeping a wake-up that comes before its raw
    subscription is stored (see the module's doc)."""

    def __init__(
        self, ctx: Context, name: str, cb: Any, notify_disconnect: bool = False
    ) -> None:
        self._lock = threading.Lock()
        self._early = False
        super().__init__(ctx, name, cb, notify_disconnect=notify_disconnect)

    def _event(self) -> None:
        with self._lock:
            if self._S is None:
                self._early = True
                return
        super()._event()

    def started(self, sub: Any) -> None:
        """Store the raw subscription; give a wake-up that came before."""
        with self._lock:
            self._S = sub
            early, self._early = self._early, False
        if early:
            super()._event()


def monitor(
    ctx: Context,
    name: str,
    cb: Any,
    request: Any = None,
    notify_disconnect: bool = False,
) -> Subscription:
    """``ctx.monitor(name, cb, request, notify_disconnect)``, free of its race."""
    sub = StartedSubscription(ctx, name, cb, notify_disconnect)
    sub.started(raw.Context.monitor(ctx, name, sub._event, request))
    return sub

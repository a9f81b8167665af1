"""Blocking proxies for one block of a ThreadedProcess and its fields."""

from __future__ import annotations

import concurrent.futures
from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING, Any

from malcolm.core import Attribute, Method, NotFoundError

if TYPE_CHECKING:
    from .threaded import EmbeddedSubscription, ThreadedProcess


class BlockProxy:
    """Attributes and methods of one block, as blocking Python attributes.

    ``proxy.name`` is a :class:`MethodProxy` or an :class:`AttributeProxy`;
    ``proxy["name"]`` does the same for names that clash with Python.
    """

    def __init__(self, owner: ThreadedProcess, mri: str) -> None:
        self._owner = owner
        self.mri = mri

    def _field(self, name: str) -> AttributeProxy | MethodProxy:
        def kind() -> type | None:
            block = self._owner.process.get_block(self.mri)
            if name not in block:
                return None
            return Method if isinstance(block[name], Method) else Attribute

        found = self._owner.call_in_loop(kind)
        if found is None:
            raise NotFoundError(
                f"{self.mri} has no field {name!r} (fields: {', '.join(self._names())})"
            )
        if found is Method:
            return MethodProxy(self._owner, self.mri, name)
        return AttributeProxy(self._owner, self.mri, name)

    def _names(self) -> list[str]:
        return self._owner.call_in_loop(
            lambda: list(self._owner.process.get_block(self.mri))
        )

    def __getitem__(self, name: str) -> AttributeProxy | MethodProxy:
        return self._field(name)

    def __getattr__(self, name: str) -> AttributeProxy | MethodProxy:
        if name.startswith("_"):
            raise AttributeError(name)
        try:
            return self._field(name)
        except NotFoundError as e:
            raise AttributeError(str(e)) from None

    def __dir__(self) -> list[str]:
        return sorted(set(super().__dir__()) | set(self._names()))

    def to_dict(self) -> dict[str, Any]:
        """The whole block as plain data."""
        return self._owner.get([self.mri])

    def __repr__(self) -> str:
        return f"<BlockProxy {self.mri}>"


class AttributeProxy:
    """One attribute: ``.value``, ``.put(v)``, ``.subscribe(cb)``, ``.when(v)``."""

    def __init__(self, owner: ThreadedProcess, mri: str, name: str) -> None:
        self._owner = owner
        self.mri = mri
        self.name = name

    @property
    def path(self) -> list[str]:
        return [self.mri, self.name]

    @property
    def value(self) -> Any:
        return self._owner.get([*self.path, "value"])

    def to_dict(self) -> dict[str, Any]:
        return self._owner.get(self.path)

    @property
    def meta(self) -> dict[str, Any]:
        return self._owner.get([*self.path, "meta"])

    def put(self, value: Any, timeout: float | None = None) -> None:
        """Put ``value``; returns when the put is complete.

        After ``timeout`` seconds raises WaitTimeoutError; the put goes on.
        """
        self._owner.put(self.path, value, timeout)

    def subscribe(
        self, callback: Callable[[Any], None], delta: bool = False
    ) -> EmbeddedSubscription:
        """``callback(value)`` now and on every change (the dispatch thread).

        With ``delta=True`` the callback gets lists of changes to the whole
        attribute (value, alarm, timeStamp...) instead.
        """
        path = self.path if delta else [*self.path, "value"]
        return self._owner.subscribe(path, callback, delta)

    def when(
        self, match: Any, timeout: float | None = None, bad_values: Iterable[Any] = ()
    ) -> Any:
        """Wait until the value equals ``match`` (or ``match(value)``)."""
        return self._owner.when([*self.path, "value"], match, timeout, bad_values)

    def __repr__(self) -> str:
        return f"<AttributeProxy {self.mri}.{self.name}>"


class MethodProxy:
    """One method: call it with keyword arguments; it returns what it returns."""

    def __init__(self, owner: ThreadedProcess, mri: str, name: str) -> None:
        self._owner = owner
        self.mri = mri
        self.name = name

    def __call__(self, **params: Any) -> Any:
        return self._owner.post([self.mri, self.name], params)

    def call(
        self, params: dict[str, Any] | None = None, timeout: float | None = None
    ) -> Any:
        """Call with a dict of parameters.

        After ``timeout`` seconds raises WaitTimeoutError; the call goes on.
        """
        return self._owner.post([self.mri, self.name], params, timeout)

    def future(self, **params: Any) -> concurrent.futures.Future[Any]:
        """Start the call and return at once (``.result()`` waits)."""
        return self._owner.post_async([self.mri, self.name], params)

    @property
    def meta(self) -> dict[str, Any]:
        return self._owner.get([self.mri, self.name, "meta"])

    def __repr__(self) -> str:
        return f"<MethodProxy {self.mri}.{self.name}()>"

"""What ``configure()`` and ``validate()`` take: the scan, plus what parts add.

A mixin of :class:`~malcolm.controllers.runnable.RunnableController`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from malcolm.core import (
    MapMeta,
    Meta,
    MethodMeta,
    NumberArrayMeta,
    StringArrayMeta,
)

if TYPE_CHECKING:
    from malcolm.core import Block
    from malcolm.core.generator import PointGeneratorMeta


def configure_generator_meta(base: type[PointGeneratorMeta]) -> Meta:
    """A ``base`` (PointGeneratorMeta) whose check of a call's argument only
    makes it plain data: ``configure()``/``validate()`` compute the scan's
    points themselves, once, in a worker thread (so the loop stays live),
    and refuse a scan that cannot be done, naming what is wrong."""

    class ConfigureGeneratorMeta(base):  # type: ignore[valid-type,misc]
        def validate(self, value: Any) -> Any:
            return self.as_data(value)

    return ConfigureGeneratorMeta("The scan to do", writeable=True)


class ConfigureArgs:
    """The arguments of ``configure()``/``validate()`` and their metas."""

    if TYPE_CHECKING:  # from the rest of RunnableController
        mri: str
        block: Block

        def add_call(self, name: str) -> None: ...

    def _init_configure_args(self, generator_meta: Meta) -> None:
        self._configure_takes: dict[str, Meta] = {
            "generator": generator_meta,
            "axesToMove": StringArrayMeta(
                "Axes a single run moves (the inner ones)", writeable=True
            ),
            "breakpoints": NumberArrayMeta(
                "int32", "Run lengths the scan is cut into", writeable=True
            ),
        }
        self._configure_required = ["generator"]
        self._configure_defaults: dict[str, Any] = {"breakpoints": ()}

    @property
    def configure_arg_names(self) -> list[str]:
        """Every argument configure() takes."""
        return list(self._configure_takes)

    def add_configure_arg(
        self, name: str, meta: Meta, default: Any, required: bool
    ) -> None:
        """A part adds an argument to configure() and validate()."""
        if name in self._configure_takes:
            raise ValueError(f"{self.mri}: configure already takes {name!r}")
        meta.writeable = True
        self._configure_takes[name] = meta
        if required:
            self._configure_required.append(name)
        elif default is not None:
            self._configure_defaults[name] = default
        self._remake_calls()

    def remove_configure_arg(self, name: str) -> None:
        if name in self._configure_takes:
            del self._configure_takes[name]
            self._configure_defaults.pop(name, None)
            if name in self._configure_required:
                self._configure_required.remove(name)
            self._remake_calls()

    def _remake_calls(self) -> None:
        for call in ("configure", "validate"):
            if call in self.block:
                self.block.remove(call)
                self.add_call(call)

    def _configure_meta(self, description: str, returns: bool) -> MethodMeta:
        takes = MapMeta(dict(self._configure_takes), list(self._configure_required))
        return MethodMeta(
            takes,
            MapMeta(dict(self._configure_takes)) if returns else MapMeta(),
            dict(self._configure_defaults),
            description=description,
        )

    def method_meta_configure(self) -> MethodMeta:
        return self._configure_meta("Validate the parameters, set up the scan", False)

    def method_meta_validate(self) -> MethodMeta:
        return self._configure_meta("Check parameters; returns them as tweaked", True)

"""Generators made of other generators (zip, concat), and `parse_generator`,
which turns any generator dict into its `Generator`."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from .errors import GeneratorError
from .fields import Fields
from .generators import (
    COMPOUND_TYPEID,
    PREFIX,
    ArrayGenerator,
    Arrays,
    Generator,
    LineGenerator,
    LissajousGenerator,
    SpiralGenerator,
    StaticGenerator,
    check_size,
)


class ZipGenerator(Generator):
    """Several generators of equal size run in step, one point from each."""

    def __init__(self, path: str, generators: list[Generator], alternate: bool) -> None:
        self.generators = generators
        axes = [a for g in generators for a in g.axes]
        units = [u for g in generators for u in g.units]
        super().__init__(path, axes, units, generators[0].size, alternate)

    @classmethod
    def parse(cls, fields: Fields) -> ZipGenerator:
        """Build from a ZipGenerator dict."""
        generators = _parse_children(fields, "zip")
        seen: dict[str, str] = {}
        for gen in generators:
            if gen.size != generators[0].size:
                raise GeneratorError(
                    gen.path,
                    f"all generators in a ZipGenerator must have the same size: "
                    f"this one has {gen.size}, the first has {generators[0].size}",
                )
            for axis in gen.axes:
                if axis in seen:
                    raise GeneratorError(
                        gen.path, f"axis {axis!r} is already used by {seen[axis]}"
                    )
                seen[axis] = gen.path
        alternate = fields.boolean("alternate", default=False)
        return cls(fields.path, generators, alternate)

    def positions_at(self, index: np.ndarray) -> Arrays:
        """Union of the children's positions."""
        return {k: v for g in self.generators for k, v in g.positions_at(index).items()}

    def bounds_at(self, index: np.ndarray) -> Arrays:
        """Union of the children's bounds."""
        return {k: v for g in self.generators for k, v in g.bounds_at(index).items()}

    def extremes(self, bounds: bool) -> list[tuple[str, str, np.ndarray]]:
        """The children's."""
        return [e for g in self.generators for e in g.extremes(bounds)]

    def check_bounds(self) -> None:
        """The children's bounds must be usable."""
        for gen in self.generators:
            gen.check_bounds()


class ConcatGenerator(Generator):
    """Several generators on the same axes, run one after the other.

    Child c covers indexes ``offsets[c] .. offsets[c+1]-1``; the bound
    between two children is the first bound of the later one, which must be
    (nearly) the last bound of the earlier one.
    """

    #: How far apart the last bound of one child and the first bound of the next
    #: may be (scanpointgenerator's limit)
    BOUNDS_TOLERANCE = 1e-5

    def __init__(self, path: str, generators: list[Generator], alternate: bool) -> None:
        self.generators = generators
        sizes = [g.size for g in generators]
        self._offsets = np.concatenate(([0], np.cumsum(sizes)))
        super().__init__(
            path, generators[0].axes, generators[0].units, sum(sizes), alternate
        )

    @classmethod
    def parse(cls, fields: Fields) -> ConcatGenerator:
        """Build from a ConcatGenerator dict."""
        generators = _parse_children(fields, "concat")
        first = generators[0]
        for gen in generators[1:]:
            if gen.axes != first.axes:
                raise GeneratorError(
                    gen.path,
                    f"all generators in a ConcatGenerator must have the same axes: "
                    f"this one has {gen.axes}, the first has {first.axes}",
                )
            if gen.units != first.units:
                raise GeneratorError(
                    gen.path,
                    f"all generators in a ConcatGenerator must have the same units: "
                    f"this one has {gen.units}, the first has {first.units}",
                )
        alternate = fields.boolean("alternate", default=False)
        return cls(fields.path, generators, alternate)

    def _gather(self, index: np.ndarray, child: np.ndarray, evaluate: str) -> Arrays:
        """Evaluate each child (``positions_at`` or ``bounds_at``) at the
        indexes it owns (``child`` says which owns each index)."""
        index = np.asarray(index)
        result = {a: np.empty(index.shape) for a in self.axes}
        for c in np.unique(child):
            mine = child == c
            gen = self.generators[c]
            values = getattr(gen, evaluate)(index[mine] - self._offsets[c])
            for axis in self.axes:
                result[axis][mine] = values[axis]
        return result

    def positions_at(self, index: np.ndarray) -> Arrays:
        """Each index from the child that owns it."""
        child = np.searchsorted(self._offsets, index, side="right") - 1
        return self._gather(index, child, "positions_at")

    def bounds_at(self, index: np.ndarray) -> Arrays:
        """Each bound from the child whose first point it starts (the last
        bound from the last child)."""
        child = np.searchsorted(self._offsets, index, side="right") - 1
        child = np.minimum(child, len(self.generators) - 1)
        return self._gather(index, child, "bounds_at")

    def extremes(self, bounds: bool) -> list[tuple[str, str, np.ndarray]]:
        """The children's."""
        return [e for g in self.generators for e in g.extremes(bounds)]

    def check_bounds(self) -> None:
        """The last bound of each child must meet the first of the next."""
        for gen in self.generators:
            gen.check_bounds()
        for axis in self.axes:
            for before, gen in zip(self.generators, self.generators[1:]):
                end = float(before.bounds_at(np.array([before.size]))[axis][0])
                begin = float(gen.bounds_at(np.array([0]))[axis][0])
                if abs(end - begin) >= self.BOUNDS_TOLERANCE:
                    raise GeneratorError(
                        gen.path,
                        f"bounds of axis {axis!r} do not join the previous "
                        f"generator's ({begin:g} != {end:g}); a continuous scan "
                        f"needs them to meet (or set continuous to false)",
                    )


def _parse_children(fields: Fields, kind: str) -> list[Generator]:
    items = fields.items("generators")
    if not items:
        raise GeneratorError(fields.at("generators"), "expected at least one generator")
    children = [parse_generator(value, path) for path, value in items]
    for child in children:
        if child.alternate:
            raise GeneratorError(
                child.path + ".alternate",
                f"must be false inside a {kind} generator; "
                f"set alternate on the {kind} generator itself",
            )
    return children


_PARSERS: dict[str, Callable[[Fields], Generator]] = {
    PREFIX + "LineGenerator:1.0": LineGenerator.parse,
    PREFIX + "SpiralGenerator:1.0": SpiralGenerator.parse,
    PREFIX + "LissajousGenerator:1.0": LissajousGenerator.parse,
    PREFIX + "ArrayGenerator:1.0": ArrayGenerator.parse,
    PREFIX + "StaticPointGenerator:1.0": StaticGenerator.parse,
    # Not a scanpointgenerator typeid, accepted as an alias
    PREFIX + "StaticGenerator:1.0": StaticGenerator.parse,
    PREFIX + "ZipGenerator:1.0": ZipGenerator.parse,
    PREFIX + "ConcatGenerator:1.0": ConcatGenerator.parse,
}


def parse_generator(data: Any, path: str) -> Generator:
    """Parse one generator dict found at ``path`` of the input."""
    fields = Fields(data, path)
    typeid = fields.string("typeid")
    if typeid == COMPOUND_TYPEID:
        raise GeneratorError(
            path, "a CompoundGenerator cannot be nested; nest its generators instead"
        )
    parser = _PARSERS.get(typeid)
    if parser is None:
        raise GeneratorError(path, f"unknown typeid {typeid!r}")
    generator = parser(fields)
    fields.check_no_extra()
    check_size(generator.size, path)
    return generator

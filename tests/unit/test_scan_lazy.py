"""Points computed lazily, a chunk at a time, equal the whole scan expanded at
once, exactly: for CompoundGenerator dicts against the eager algorithm
malcolm used before (tests/unit/scan_oracle.py), and for scanspec Specs
against scanspec's own Path."""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scanspec.core import Path
from scanspec.specs import Fly, Linspace, Spec, Spiral, Squash, Static

from malcolm.scan import GeneratorError, ScanPoints, scan_points
from malcolm.scan.regions import find_runs

from .scan_oracle import oracle_points

P = "scanpointgenerator:generator/"
ROI = "scanpointgenerator:roi/"
EXCLUDER = "scanpointgenerator:excluder/ROIExcluder:1.0"
SETTINGS = settings(
    max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)

numbers = st.one_of(
    st.integers(-5, 5).map(float),
    st.floats(-5, 5, allow_nan=False, allow_infinity=False),
)


def same(actual: np.ndarray, expected: np.ndarray) -> bool:
    """Equal bit for bit (so -0.0 is not 0.0), as float64."""
    actual = np.asarray(actual)
    return (
        actual.dtype == np.float64
        and actual.tobytes() == np.asarray(expected, dtype=np.float64).tobytes()
    )


# -- CompoundGenerator dicts ---------------------------------------------------


def line(axis, start, stop, size, alternate=False):
    return {
        "typeid": P + "LineGenerator:1.0",
        "axes": [axis],
        "units": ["mm"],
        "start": [start],
        "stop": [stop],
        "size": size,
        "alternate": alternate,
    }


@st.composite
def one_generator(draw: Any, axes: list[str], alternate: bool) -> dict[str, Any]:
    """A generator on the next one or two of ``axes`` (which it consumes)."""
    kind = draw(
        st.sampled_from(
            ["line", "line", "line", "spiral", "lissajous", "array", "static"]
            + ["zip", "concat", "line2"]
        )
    )
    if kind in ("spiral", "lissajous", "zip", "line2") and len(axes) < 2:
        kind = "line"
    if kind == "line":
        return line(
            axes.pop(0),
            draw(numbers),
            draw(numbers),
            draw(st.integers(1, 6)),
            alternate,
        )
    if kind == "line2":
        a, b = axes.pop(0), axes.pop(0)
        return {
            "typeid": P + "LineGenerator:1.0",
            "axes": [a, b],
            "start": [draw(numbers), draw(numbers)],
            "stop": [draw(numbers), draw(numbers)],
            "size": draw(st.integers(1, 5)),
            "alternate": alternate,
        }
    if kind == "spiral":
        a, b = axes.pop(0), axes.pop(0)
        return {
            "typeid": P + "SpiralGenerator:1.0",
            "axes": [a, b],
            "centre": [draw(numbers), draw(numbers)],
            "radius": draw(st.floats(0, 4)),
            "scale": draw(st.floats(0.5, 3)),
            "alternate": alternate,
        }
    if kind == "lissajous":
        a, b = axes.pop(0), axes.pop(0)
        return {
            "typeid": P + "LissajousGenerator:1.0",
            "axes": [a, b],
            "centre": [draw(numbers), draw(numbers)],
            "span": [draw(numbers), draw(numbers)],
            "lobes": draw(st.integers(1, 3)),
            "size": draw(st.integers(1, 12)),
            "alternate": alternate,
        }
    if kind == "array":
        return {
            "typeid": P + "ArrayGenerator:1.0",
            "axes": [axes.pop(0)],
            "points": draw(st.lists(numbers, min_size=2, max_size=5)),
            "alternate": alternate,
        }
    if kind == "static":
        static: dict[str, Any] = {
            "typeid": P + "StaticPointGenerator:1.0",
            "size": draw(st.integers(1, 3)),
        }
        if draw(st.booleans()):
            static["axes"] = [axes.pop(0)]
        return static
    if kind == "zip":
        size = draw(st.integers(1, 5))
        a, b = axes.pop(0), axes.pop(0)
        return {
            "typeid": P + "ZipGenerator:1.0",
            "generators": [
                line(a, draw(numbers), draw(numbers), size),
                line(b, draw(numbers), draw(numbers), size),
            ],
            "alternate": alternate,
        }
    axis = axes.pop(0)
    first = line(axis, draw(numbers), draw(numbers), draw(st.integers(1, 4)))
    if draw(st.booleans()):  # a second piece that joins the first's bounds
        step = (first["stop"][0] - first["start"][0]) / max(1, first["size"] - 1)
        start = first["stop"][0] + step
        second = line(axis, start, start + 2 * step, 3)
    else:
        second = line(axis, draw(numbers), draw(numbers), draw(st.integers(1, 4)))
    return {
        "typeid": P + "ConcatGenerator:1.0",
        "generators": [first, second],
        "alternate": alternate,
    }


@st.composite
def rois(draw: Any) -> dict[str, Any]:
    kind = draw(
        st.sampled_from(
            [
                "circle",
                "rectangle",
                "rectangle",
                "ellipse",
                "polygon",
                "sector",
                "point",
            ]
        )
    )
    if kind == "circle":
        return {
            "typeid": ROI + "CircularROI:1.0",
            "centre": [draw(numbers), draw(numbers)],
            "radius": draw(st.floats(0.5, 6)),
        }
    if kind == "rectangle":
        return {
            "typeid": ROI + "RectangularROI:1.0",
            "start": [draw(numbers), draw(numbers)],
            "width": draw(st.floats(0.5, 8)),
            "height": draw(st.floats(0.5, 8)),
            "angle": draw(st.sampled_from([0.0, 0.0, 0.4])),
        }
    if kind == "ellipse":
        return {
            "typeid": ROI + "EllipticalROI:1.0",
            "centre": [draw(numbers), draw(numbers)],
            "semiaxes": [draw(st.floats(0.5, 5)), draw(st.floats(0.5, 5))],
            "angle": draw(st.floats(0, 3)),
        }
    if kind == "polygon":
        return {
            "typeid": ROI + "PolygonalROI:1.0",
            "points_x": [-5.0, draw(numbers), 5.0],
            "points_y": [-5.0, 5.0, draw(numbers)],
        }
    if kind == "sector":
        return {
            "typeid": ROI + "SectorROI:1.0",
            "centre": [draw(numbers), draw(numbers)],
            "radii": [0.0, draw(st.floats(1, 8))],
            "angles": [draw(st.floats(0, 3)), draw(st.floats(3, 7))],
        }
    point = draw(st.sampled_from([[0.0, 0.0], [1.0, 1.0], [-5.0, 5.0]]))
    return {"typeid": ROI + "PointROI:1.0", "point": point}


@st.composite
def compounds(draw: Any) -> dict[str, Any]:
    axes = ["a", "b", "c", "d", "e", "f", "g", "h"]
    count = draw(st.sampled_from([1, 2, 2, 3, 3]))
    generators = []
    for _ in range(count):
        generators.append(draw(one_generator(axes, draw(st.booleans()))))
    scanned = list(
        dict.fromkeys(
            a
            for g in generators
            for a in g.get("axes", [])
            + [x for c in g.get("generators", []) for x in c["axes"]]
        )
    )
    excluders = []
    if len(scanned) >= 2 and draw(st.integers(0, 3)):
        for _ in range(draw(st.integers(1, 2))):
            pair = draw(st.permutations(scanned))[:2]
            excluders.append(
                {
                    "typeid": EXCLUDER,
                    "axes": pair,
                    "rois": draw(st.lists(rois(), min_size=1, max_size=2)),
                }
            )
    data: dict[str, Any] = {
        "typeid": P + "CompoundGenerator:1.0",
        "generators": generators,
        "excluders": excluders,
        "mutators": [],
        "continuous": draw(st.booleans()),
    }
    duration = draw(st.sampled_from([None, -1.0, 0.0, 0.25]))
    if duration is not None:
        data["duration"] = duration
    return data


def boundaries(size: int, cuts: list[int]) -> list[int]:
    return sorted({0, size} | {c % (size + 1) for c in cuts})


def check_against(points: ScanPoints, expected: dict[str, Any], cuts: list[int]):
    """Whole arrays, chunks at ``cuts``, single points and the JSON text all
    equal the expected whole-scan arrays."""
    axes = expected["axes"]
    size = len(expected["positions"][axes[0]]) if axes else points.size
    assert points.axes == axes
    assert points.shape == expected["shape"]
    assert points.size == size
    assert [(d.axes, d.size, d.snake) for d in points.dimensions] == expected[
        "dimensions"
    ]
    kinds = ("positions", "lower", "upper")
    for kind in kinds:
        assert list(getattr(points, kind)) == axes
        for axis in axes:
            assert same(getattr(points, kind)[axis], expected[kind][axis]), (kind, axis)
    if expected["duration"] is None:
        assert points.duration is None and not points.has_duration
    else:
        assert same(points.duration, expected["duration"])
    edges = boundaries(size, cuts)
    chunks = [points.chunk(a, b) for a, b in zip(edges, edges[1:])]
    for kind in kinds:
        for axis in axes:
            joined = np.concatenate([getattr(c, kind)[axis] for c in chunks])
            assert same(joined, expected[kind][axis]), (kind, axis, edges)
    if expected["duration"] is not None:
        joined = np.concatenate([c.duration for c in chunks])
        assert same(joined, expected["duration"])
    else:
        assert all(c.duration is None for c in chunks)
    fresh = points.copy()  # nothing computed yet: single points from scratch
    for step in edges[:-1]:
        assert fresh.point(step) == {a: expected["positions"][a][step] for a in axes}
        for axis in axes:
            assert fresh.position(axis, step) == expected["positions"][axis][step]
        if expected["duration"] is not None:
            assert fresh.duration_at(step) == expected["duration"][step]
    whole = {
        "axes": axes,
        "size": size,
        "shape": expected["shape"],
        **{k: {a: expected[k][a].tolist() for a in axes} for k in kinds},
        "duration": None
        if expected["duration"] is None
        else expected["duration"].tolist(),
    }
    text = json.dumps(whole, allow_nan=False)
    chunk_size = max(1, min(edges[1:] or [1]))
    assert "".join(points.copy().iter_json(chunk_size)) == text
    assert json.dumps(points.copy().to_json()) == text


@SETTINGS
@given(data=compounds(), cuts=st.lists(st.integers(0, 10**6), max_size=4))
def test_compound_lazy_equals_eager(data, cuts):
    try:
        expected = oracle_points(data)
    except GeneratorError as e:
        with pytest.raises(GeneratorError) as info:
            scan_points(data)
        assert str(info.value) == str(e)
        return
    check_against(scan_points(data), expected, cuts)


huge = st.one_of(
    numbers,
    st.floats(-1.7e308, 1.7e308, allow_nan=False, allow_infinity=False),
    st.sampled_from([1e308, -1e308, 1.7e308, -1.7e308, 8e307, -8e307]),
)


@st.composite
def huge_compounds(draw: Any) -> dict[str, Any]:
    """Compounds whose numbers may overflow (and no region)."""
    kind = draw(st.sampled_from(["line", "spiral", "lissajous", "array", "concat"]))
    if kind == "line":
        gen = line("x", draw(huge), draw(huge), draw(st.integers(1, 4)))
    elif kind == "spiral":
        scale = draw(st.sampled_from([1.0, 1e300, 1e307, 1.7e308]))
        gen = {
            "typeid": P + "SpiralGenerator:1.0",
            "axes": ["x", "w"],
            "centre": [draw(huge), draw(huge)],
            "radius": min(1.7e308, draw(st.sampled_from([0.0, 1.0, 3.0, 6.0])) * scale),
            "scale": scale,
        }
    elif kind == "lissajous":
        gen = {
            "typeid": P + "LissajousGenerator:1.0",
            "axes": ["x", "w"],
            "centre": [draw(huge), draw(huge)],
            "span": [draw(huge), draw(huge)],
            "lobes": 1,
            "size": draw(st.integers(1, 6)),
        }
    elif kind == "array":
        gen = {
            "typeid": P + "ArrayGenerator:1.0",
            "axes": ["x"],
            "points": draw(st.lists(huge, min_size=2, max_size=4)),
        }
    else:
        gen = {
            "typeid": P + "ConcatGenerator:1.0",
            "generators": [
                line("x", draw(huge), draw(huge), draw(st.integers(1, 3)))
                for _ in range(2)
            ],
        }
    outer = line("y", draw(huge), draw(huge), draw(st.integers(1, 3)))
    generators = [outer, gen] if draw(st.booleans()) else [gen, outer]
    return {
        "typeid": P + "CompoundGenerator:1.0",
        "generators": generators,
        "continuous": draw(st.booleans()),
    }


@settings(SETTINGS, max_examples=600)
@given(data=huge_compounds())
def test_numbers_too_large_are_refused_as_before(data):
    """What overflows is refused without computing every point, naming the
    generator, where the eager algorithm refused it; and where a curve's box
    (centre +- its reach) overflows though no point of it does, which is
    within a factor of a few of the largest float."""
    try:
        expected = oracle_points(data)
    except GeneratorError as e:
        with pytest.raises(GeneratorError) as info:
            scan_points(data)
        if "not all finite" in str(e):
            assert info.value.path.startswith("generators[")
            assert "are not all finite (inputs too large?)" in info.value.reason
        else:
            assert str(info.value) == str(e)
        return
    curves = ("Spiral", "Lissajous")
    try:
        points = scan_points(data)
    except GeneratorError as e:
        assert "are not all finite" in e.reason
        curve = data["generators"][int(e.path[len("generators[")])]
        assert curve["typeid"].endswith(tuple(f"{c}Generator:1.0" for c in curves))
        largest = max(
            float(np.max(np.abs(expected[k][a])))
            for k in ("positions", "lower", "upper")
            for a in curve["axes"]
        )
        assert largest > 1e307
        return
    check_against(points, expected, [1, 3])


def test_chunks_of_a_snake_grid_with_a_region():
    data = {
        "typeid": P + "CompoundGenerator:1.0",
        "generators": [
            line("z", 0, 1, 3),
            line("y", 0, 4, 9, alternate=True),
            line("x", 0, 4, 9, alternate=True),
        ],
        "excluders": [
            {
                "typeid": EXCLUDER,
                "axes": ["x", "y"],
                "rois": [
                    {"typeid": ROI + "CircularROI:1.0", "centre": [2, 2], "radius": 2}
                ],
            }
        ],
        "duration": 0.5,
    }
    points = scan_points(data)
    assert points.shape[0] == 3 and points.shape[1] < 81
    check_against(points, oracle_points(data), [5, 17, 40, 41])


@given(
    kept=st.lists(st.booleans(), min_size=1, max_size=60),
    chunk=st.integers(1, 8),
)
def test_kept_runs_map_kept_indexes_across_chunk_boundaries(kept, chunk):
    mask = np.array(kept)
    runs = find_runs(len(mask), lambda t: mask[t], chunk)
    expected = np.flatnonzero(mask)
    assert runs.size == len(expected)
    assert runs.unrolled(np.arange(runs.size)).tolist() == expected.tolist()
    # one run per stretch of consecutive kept points, wherever chunks end
    assert len(runs.starts) == int(np.sum(np.diff(np.r_[0, mask.astype(int)]) == 1))


def test_a_concat_join_takes_the_later_piece_first_bound():
    # the pieces meet within the tolerance, not exactly: 1.5 and 1.5000001
    concat = {
        "typeid": P + "ConcatGenerator:1.0",
        "generators": [line("x", 0, 1, 2), line("x", 2.0000001, 3.0000001, 2)],
        "alternate": True,
    }
    data = {
        "typeid": P + "CompoundGenerator:1.0",
        "generators": [line("y", 0, 1, 2), concat],
    }
    points = scan_points(data)
    assert points.lower["x"][2] == points.upper["x"][1] == 2.0000001 - 0.5
    check_against(points, oracle_points(data), [1, 2, 3, 6])


def test_chunks_iterate_the_whole_scan():
    points = scan_points(
        {
            "typeid": P + "CompoundGenerator:1.0",
            "generators": [line("y", 0, 1, 7), line("x", 0, 1, 5, alternate=True)],
        }
    )
    pieces = list(points.chunks(chunk_size=4, start=3, stop=30))
    assert [(c.start, c.stop, len(c)) for c in pieces][:2] == [(3, 7, 4), (7, 11, 4)]
    assert pieces[-1].stop == 30
    joined = np.concatenate([c.positions["x"] for c in pieces])
    assert same(joined, points.positions["x"][3:30])
    only_x = points.chunk(3, 9, axes=["x"])
    assert list(only_x.positions) == ["x"] and list(only_x.lower) == ["x"]
    assert same(only_x.upper["x"], points.upper["x"][3:9])


def test_bad_ranges_and_axes_are_named():
    points = scan_points(
        {"typeid": P + "CompoundGenerator:1.0", "generators": [line("x", 0, 1, 4)]}
    )
    with pytest.raises(IndexError, match="steps 2 to 5 are not a range of the 4"):
        points.chunk(2, 5)
    with pytest.raises(IndexError, match="steps 3 to 2"):
        points.chunk(3, 2)
    with pytest.raises(KeyError, match="'q' is not an axis"):
        points.chunk(0, 1, axes=["q"])
    with pytest.raises(KeyError, match="'q'"):
        points.position("q", 0)
    with pytest.raises(IndexError, match="point 4 is out of range for 4 points"):
        points.point(4)
    with pytest.raises(ValueError, match="chunk_size must be at least 1, got 0"):
        points.chunks(0)  # said when called, not when first iterated
    with pytest.raises(ValueError, match="chunk_size must be at least 1"):
        points.iter_json(-1)
    with pytest.raises(TypeError, match="start must be an integer, got float"):
        points.chunk(1.5, 3)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="index must be an integer, got str"):
        points.point("1")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="chunk_size must be an integer"):
        points.column("positions", "x", 2.0)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="unknown kind 'middle'"):
        points.column("middle", "x")
    with pytest.raises(ValueError, match="positions are of an axis"):
        points.column("positions")
    with pytest.raises(ValueError, match="does not say how long"):
        points.column("duration")
    with pytest.raises(KeyError, match="'q'"):
        points.chunks(axes=["q"])
    assert points.chunk(np.int64(1), np.int32(3)).positions["x"].tolist() == [
        1 / 3,
        2 / 3,
    ]
    assert points.point(-1) == {"x": 1.0}
    assert points.duration_at(0) is None
    assert len(points.chunk(4, 4)) == 0


def test_arrays_handed_out_are_read_only():
    points = scan_points(
        {"typeid": P + "CompoundGenerator:1.0", "generators": [line("x", 0, 1, 4)]}
    )
    with pytest.raises(ValueError, match="read-only"):
        points.positions["x"][0] = 5
    with pytest.raises(ValueError, match="read-only"):
        points.chunk(0, 2).lower["x"][0] = 5


# -- scanspec Specs: equal to scanspec's own Path ------------------------------


@st.composite
def specs(draw: Any) -> Spec[str]:
    names = iter("abcdefgh")
    count = draw(st.integers(1, 3))
    parts: list[Spec[str]] = []
    for i in range(count):
        kind = draw(st.sampled_from(["line", "line", "zip", "concat", "static"]))
        if kind == "line":
            part = Linspace(
                next(names), draw(numbers), draw(numbers), draw(st.integers(1, 5))
            )
        elif kind == "zip":
            num = draw(st.integers(1, 4))
            part = Linspace(next(names), draw(numbers), draw(numbers), num).zip(
                Linspace(next(names), draw(numbers), draw(numbers), num)
            )
        elif kind == "concat":
            axis = next(names)
            part = Linspace(axis, draw(numbers), draw(numbers), draw(st.integers(1, 3)))
            part = part.concat(
                Linspace(axis, draw(numbers), draw(numbers), draw(st.integers(1, 3)))
            )
        else:
            part = Static(next(names), draw(numbers), draw(st.integers(1, 3)))
        if i and draw(st.booleans()):
            part = ~part
        parts.append(part)
    spec = parts[0]
    for part in parts[1:]:
        spec = spec * part
    if count > 1 and draw(st.booleans()):
        spec = Squash(spec, check_path_changes=False)
    if draw(st.booleans()):
        spec = Fly(spec)
    if draw(st.booleans()):
        spec = draw(st.sampled_from([0.1, 0.5])) @ spec
    return spec


def path_points(spec: Spec[str]) -> dict[str, Any]:
    """What malcolm computed before: scanspec's whole Path at once."""
    stack = spec.calculate()
    frames = Path(stack).consume()
    axes = [a for dim in stack for a in dim.axes()]
    return {
        "axes": axes,
        "shape": [len(d) for d in stack],
        "dimensions": [
            (list(d.axes()), len(d), type(d).__name__ == "SnakedDimension")
            for d in stack
        ],
        **{
            kind: {a: np.asarray(source[a], dtype=float) for a in axes}
            for kind, source in (
                ("positions", frames.midpoints),
                ("lower", frames.lower),
                ("upper", frames.upper),
            )
        },
        "duration": None
        if frames.duration is None
        else np.asarray(frames.duration, dtype=float),
    }


@SETTINGS
@given(spec=specs(), cuts=st.lists(st.integers(0, 10**6), max_size=4))
def test_spec_lazy_equals_scanspec_path(spec, cuts):
    try:
        expected = path_points(spec)
    except Exception:
        with pytest.raises(GeneratorError):
            scan_points(spec)
        return
    check_against(scan_points(spec), expected, cuts)
    check_against(scan_points(dict(spec.serialize())), expected, cuts)


def test_spec_snake_durations_follow_scanspec():
    spec = Linspace("y", 0, 1, 3) * ~Fly(0.1 @ Linspace("x", 0, 1, 3)).concat(
        Fly(0.2 @ Linspace("x", 1.5, 2, 2))
    )
    expected = path_points(spec)
    assert len(set(expected["duration"].tolist())) == 2
    check_against(scan_points(spec), expected, [4, 7])


def test_spiral_spec():
    spec = Fly(0.1 @ Spiral("x", 0, 10, 2, "y", 5))
    check_against(scan_points(spec), path_points(spec), [3, 11])

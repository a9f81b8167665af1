"""Malformed input raises GeneratorError naming where the problem is."""

from __future__ import annotations

import copy
import json
import math

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from malcolm.scan import GeneratorError, scan_points
from malcolm.scan.files import points_from_file

P = "scanpointgenerator:generator/"
ROI = "scanpointgenerator:roi/"
EXCLUDER = "scanpointgenerator:excluder/ROIExcluder:1.0"


def line(axis="x", size=3, alternate=False):
    return {
        "typeid": P + "LineGenerator:1.0",
        "axes": [axis],
        "units": ["mm"],
        "start": [0],
        "stop": [1],
        "size": size,
        "alternate": alternate,
    }


def good() -> dict:
    """A valid generator exercising every kind of item, to break piece by piece."""
    return {
        "typeid": P + "CompoundGenerator:1.0",
        "generators": [
            line("z", 2),
            {
                "typeid": P + "ZipGenerator:1.0",
                "generators": [line("y"), line("w")],
                "alternate": True,
            },
            line("x", 4, alternate=True),
        ],
        "excluders": [
            {
                "typeid": EXCLUDER,
                "axes": ["x", "y"],
                "rois": [
                    {
                        "typeid": ROI + "CircularROI:1.0",
                        "centre": [0.5, 0.5],
                        "radius": 1,
                    }
                ],
            }
        ],
        "mutators": [],
        "duration": 0.1,
        "continuous": True,
        "delay_after": 0.0,
    }


def test_good_is_good():
    points = scan_points(good())
    assert points.shape[0] == 2 and points.size > 2


def broken(path: str, value=None, delete=False) -> dict:
    """good() with the item at a dotted path replaced (or deleted)."""
    data = good()
    keys = [int(k) if k.isdigit() else k for k in path.split(".")]
    target = data
    for key in keys[:-1]:
        target = target[key]
    if delete:
        del target[keys[-1]]
    else:
        target[keys[-1]] = value
    return data


CASES = [
    # (path to change, new value or "DELETE", expected message)
    ("generators", "DELETE", "generators: missing required key"),
    ("generators", [], "generators: expected at least one generator"),
    ("generators", {}, "generators: expected a list, got a mapping"),
    (
        "generators.0.size",
        -3,
        "generators[0].size: expected a positive integer, got -3",
    ),
    ("generators.0.size", 0, "generators[0].size: expected a positive integer, got 0"),
    (
        "generators.0.size",
        2.5,
        "generators[0].size: expected a positive integer, got 2.5",
    ),
    (
        "generators.0.size",
        "3",
        "generators[0].size: expected a positive integer, got '3'",
    ),
    (
        "generators.0.size",
        True,
        "generators[0].size: expected a positive integer, got true",
    ),
    ("generators.0.size", "DELETE", "generators[0].size: missing required key"),
    ("generators.0.typeid", "x", "generators[0]: unknown typeid 'x'"),
    ("generators.0.typeid", "DELETE", "generators[0].typeid: missing required key"),
    ("generators.0.start", [0, 1], "generators[0].start: expected 1 numbers, got 2"),
    ("generators.0.start", ["a"], "generators[0].start[0]: expected a number, got 'a'"),
    (
        "generators.0.stop",
        [math.nan],
        "generators[0].stop[0]: expected a finite number",
    ),
    ("generators.0.axes", ["z", "z"], "generators[0].axes: axis 'z' is given twice"),
    ("generators.0.axes", [], "generators[0].start: expected 0 numbers, got 1"),
    ("generators.0.axes", [3], "generators[0].axes[0]: expected a string, got 3"),
    ("generators.0.units", ["mm", "deg"], "generators[0].units: expected 1 units"),
    (
        "generators.0.alternate",
        "yes",
        "generators[0].alternate: expected true or false",
    ),
    ("generators.0.sise", 3, "generators[0].sise: unknown key"),
    ("generators.0", 5, "generators[0]: expected a mapping, got 5"),
    (
        "generators.0.axes",
        ["x"],
        "generators[2]: axis 'x' is already used by generators[0]",
    ),
    (
        "generators.1.generators.1.size",
        4,
        "generators[1].generators[1]: all generators in a ZipGenerator must have "
        "the same size",
    ),
    (
        "generators.1.generators.0.alternate",
        True,
        "generators[1].generators[0].alternate: must be false inside a zip generator",
    ),
    (
        "generators.1.generators",
        [],
        "generators[1].generators: expected at least one generator",
    ),
    (
        "generators.1.generators.1.axes",
        ["y"],
        "generators[1].generators[1]: axis 'y' is already used by "
        "generators[1].generators[0]",
    ),
    (
        "generators.2.typeid",
        P + "CompoundGenerator:1.0",
        "generators[2]: a CompoundGenerator cannot be nested",
    ),
    ("excluders.0.typeid", "x", "excluders[0]: unknown typeid 'x'"),
    (
        "excluders.0.axes",
        ["x", "q"],
        "excluders[0].axes: axis 'q' is not scanned by any generator",
    ),
    ("excluders.0.axes", ["x"], "excluders[0].axes: expected 2 axes, got 1"),
    ("excluders.0.rois", [], "excluders[0].rois: expected at least one ROI"),
    (
        "excluders.0.rois.0.radius",
        "DELETE",
        "excluders[0].rois[0].radius: missing required key",
    ),
    (
        "excluders.0.rois.0.radius",
        -1,
        "excluders[0].rois[0].radius: expected a positive number, got -1",
    ),
    (
        "excluders.0.rois.0.centre",
        [1],
        "excluders[0].rois[0].centre: expected 2 numbers, got 1",
    ),
    (
        "excluders.0.rois.0.typeid",
        ROI + "Hexagon:1.0",
        f"excluders[0].rois[0]: unknown typeid '{ROI}Hexagon:1.0'",
    ),
    (
        "excluders.0.rois.0.centre",
        [100, 100],
        "excluders[0]: regions would exclude the entire scan",
    ),
    ("generators.2.alternate", False, "excluders[0]: its region joins"),
    (
        "mutators",
        [
            {
                "typeid": "scanpointgenerator:mutator/RandomOffsetMutator:1.0",
                "seed": 1,
                "axes": ["x"],
                "max_offset": [0.1],
            }
        ],
        "mutators[0]: RandomOffsetMutator is not supported",
    ),
    ("mutators", [{"typeid": "x"}], "mutators[0]: unknown typeid 'x'"),
    ("mutators", None, "mutators: expected a list, got null"),
    ("duration", "fast", "duration: expected a number, got 'fast'"),
    ("continuous", 1, "continuous: expected true or false, got 1"),
    ("delay_after", [], "delay_after: expected a number, got a list of 0"),
    (
        "typeid",
        P + "LineGenerator:1.0",
        "typeid: expected 'scanpointgenerator:generator/CompoundGenerator:1.0'",
    ),
    ("typeid", "DELETE", "typeid: missing required key"),
]


@pytest.mark.parametrize(("path", "value", "message"), CASES, ids=[c[2] for c in CASES])
def test_malformed(path, value, message):
    data = (
        broken(path, delete=value == "DELETE")
        if value == "DELETE"
        else broken(path, value)
    )
    with pytest.raises(GeneratorError) as info:
        scan_points(data)
    assert str(info.value).startswith(message)
    assert isinstance(info.value, ValueError)


def test_generator_error_has_path_and_reason():
    with pytest.raises(GeneratorError) as info:
        scan_points(broken("generators.0.size", -3))
    assert info.value.path == "generators[0].size"
    assert info.value.reason == "expected a positive integer, got -3"


@pytest.mark.parametrize(
    ("generator", "message"),
    [
        (
            {
                "typeid": P + "SpiralGenerator:1.0",
                "axes": ["a", "b"],
                "centre": [0, 0],
                "radius": 1,
                "scale": 0,
            },
            "generators[0].scale: expected a positive number, got 0",
        ),
        (
            {
                "typeid": P + "SpiralGenerator:1.0",
                "axes": ["a"],
                "centre": [0, 0],
                "radius": 1,
            },
            "generators[0].axes: expected 2 axes, got 1",
        ),
        (
            {
                "typeid": P + "SpiralGenerator:1.0",
                "axes": ["a", "b"],
                "centre": [0, 0],
                "radius": 1e9,
                "scale": 1e-3,
            },
            "generators[0]: spiral would have more than",
        ),
        (
            {
                "typeid": P + "LissajousGenerator:1.0",
                "axes": ["a", "b"],
                "centre": [0, 0],
                "span": [1],
                "lobes": 2,
            },
            "generators[0].span: expected 2 numbers, got 1",
        ),
        (
            {
                "typeid": P + "LineGenerator:1.0",
                "axes": ["x"],
                "start": [0],
                "stop": [1],
                "size": 10**12,
            },
            "generators[0]: scan would have 1000000000000 points",
        ),
        (
            {"typeid": P + "StaticPointGenerator:1.0", "size": 2, "axes": ["a", "b"]},
            "generators[0].axes: expected at most 1 axis, got 2",
        ),
        (
            {"typeid": P + "ArrayGenerator:1.0", "axes": ["a"], "points": [1]},
            "generators[0].points: expected at least 2 points, got 1",
        ),
        (
            {"typeid": P + "ConcatGenerator:1.0", "generators": [line("x"), line("y")]},
            "generators[0].generators[1]: all generators in a ConcatGenerator "
            "must have the same axes",
        ),
    ],
)
def test_malformed_generators(generator, message):
    data = {"typeid": P + "CompoundGenerator:1.0", "generators": [generator]}
    with pytest.raises(GeneratorError) as info:
        scan_points(data)
    assert str(info.value).startswith(message)


def test_rectangle_excluding_a_whole_line():
    data = good()
    data["generators"] = [line("y"), line("x")]
    data["excluders"] = [
        {
            "typeid": EXCLUDER,
            "axes": ["x", "y"],
            "rois": [
                {
                    "typeid": ROI + "RectangularROI:1.0",
                    "start": [5, 0],
                    "width": 1,
                    "height": 1,
                }
            ],
        }
    ]
    with pytest.raises(
        GeneratorError,
        match=r"^excluders\[0\]: region excludes every point of axis 'x'",
    ):
        scan_points(data)


@pytest.mark.parametrize(
    ("data", "message"),
    [
        (
            [1, 2],
            "expected a mapping (a CompoundGenerator or a serialized scanspec "
            "Spec), got a list of 2",
        ),
        ({"generator": 3}, "typeid: missing required key"),
        (
            {"type": "Hexagon"},
            "type: Input tag 'Hexagon' found using 'type' does not match",
        ),
        (
            {"type": "Linspace", "axis": "x", "start": 0, "stop": 1, "num": 0},
            "num: Input should be greater than or equal to 1, got 0",
        ),
        (
            {
                "type": "Fly",
                "spec": {"type": "Linspace", "axis": "x", "start": "a", "stop": 1},
            },
            "spec.start: Input should be a valid number",
        ),
        (
            {"type": "Linspace", "axis": "x", "start": 0, "stop": 1, "colour": 1},
            "colour: Unexpected keyword argument",
        ),
        (
            {
                "generator": {
                    "type": "Linspace",
                    "axis": "x",
                    "start": 0,
                    "stop": 1,
                    "num": -1,
                }
            },
            "generator.num: Input should be greater than or equal to 1",
        ),
        (
            {
                "generator": {
                    "typeid": P + "CompoundGenerator:1.0",
                    "generators": [line(size=0)],
                }
            },
            "generator.generators[0].size: expected a positive integer, got 0",
        ),
    ],
)
def test_malformed_top_level_and_scanspec(data, message):
    with pytest.raises(GeneratorError) as info:
        scan_points(data)
    assert str(info.value).startswith(message)


def test_not_a_generator_at_all():
    with pytest.raises(GeneratorError, match="^expected a mapping .*, got 42$"):
        scan_points(42)  # type: ignore[arg-type]


def test_scanspec_that_cannot_be_calculated():
    bad_zip = {
        "type": "Zip",
        "left": {"type": "Linspace", "axis": "x", "start": 0, "stop": 1, "num": 2},
        "right": {"type": "Linspace", "axis": "y", "start": 0, "stop": 1, "num": 3},
    }
    with pytest.raises(GeneratorError, match="^cannot calculate the scan"):
        scan_points(bad_zip)


@pytest.mark.parametrize(
    ("name", "text", "message"),
    [
        ("bad.json", "{not json", ":1: invalid JSON: "),
        ("bad.yaml", "a: [1, 2", ":1: YAML error: "),
        (
            "empty.yaml",
            "",
            ": expected a mapping (a CompoundGenerator or a serialized scanspec "
            "Spec), got null",
        ),
        ("list.json", "[]", ": expected a mapping"),
    ],
)
def test_bad_files(tmp_path, name, text, message):
    file = tmp_path / name
    file.write_text(text)
    with pytest.raises(GeneratorError) as info:
        points_from_file(file)
    assert str(info.value).startswith(f"{file}{message}")


def test_missing_file(tmp_path):
    file = tmp_path / "absent.json"
    with pytest.raises(GeneratorError, match="absent.json: cannot read file: No such"):
        points_from_file(file)


# -- fuzzing: any corruption gives a result or a GeneratorError ---------------

JUNK = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(10**20), 10**20),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=5),
    st.lists(st.integers(-3, 3), max_size=3),
    st.dictionaries(
        st.sampled_from(["typeid", "axes", "size"]), st.integers(0, 3), max_size=2
    ),
)


def _leaf_paths(obj, prefix=()):
    yield prefix
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from _leaf_paths(v, (*prefix, k))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            yield from _leaf_paths(v, (*prefix, i))


PATHS = [p for p in _leaf_paths(good()) if p]


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(path=st.sampled_from(PATHS), junk=JUNK, delete=st.booleans())
def test_fuzzed_generator_never_crashes(path, junk, delete):
    data = copy.deepcopy(good())
    target = data
    for key in path[:-1]:
        target = target[key]
    if delete and isinstance(target, dict):
        del target[path[-1]]
    else:
        target[path[-1]] = junk
    try:
        points = scan_points(data)
    except GeneratorError as e:
        assert str(e)
        return
    assert points.size == len(points.positions[points.axes[0]])
    json.dumps(points.to_json())

"""Scan points from CompoundGenerator dicts and scanspec Specs."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scanspec.specs import Concat, Fly, Linspace, Spiral, Static, Zip

from malcolm.scan import Dimension, GeneratorError, ScanPoints, scan_points
from malcolm.scan.files import points_from_file

CASES_FILE = Path(__file__).parents[3] / "shared" / "scanpoints" / "cases.json"
TOL = 1e-9

P = "scanpointgenerator:generator/"
COMPOUND = P + "CompoundGenerator:1.0"
ROI_EXCLUDER = "scanpointgenerator:excluder/ROIExcluder:1.0"


def _load_cases() -> list[dict]:
    if not CASES_FILE.exists():
        return []
    return json.loads(CASES_FILE.read_text())


CASES = _load_cases()


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


def compound(*generators, excluders=(), duration=0.1, continuous=True):
    return {
        "typeid": COMPOUND,
        "generators": list(generators),
        "excluders": list(excluders),
        "mutators": [],
        "duration": duration,
        "continuous": continuous,
        "delay_after": 0.0,
    }


def assert_close(actual: dict, expected: dict) -> None:
    assert list(actual) == list(expected)
    for axis, values in expected.items():
        np.testing.assert_allclose(actual[axis], values, rtol=0, atol=TOL)


def assert_points(points: ScanPoints, expected: dict) -> None:
    """Compare to a dict shaped like a cases.json entry."""
    assert points.axes == expected["axes"]
    assert points.shape == expected["shape"]
    if "size" in expected:
        assert points.size == expected["size"]
    for key in ("positions", "lower", "upper"):
        assert_close(getattr(points, key), expected[key])
    if "duration" in expected:
        np.testing.assert_allclose(points.duration, expected["duration"], atol=TOL)


# -- the reference cases recorded from scanpointgenerator 3.1 ---------------


@pytest.mark.skipif(not CASES, reason=f"reference data {CASES_FILE} is absent")
@pytest.mark.parametrize("case", CASES, ids=[c["name"] for c in CASES])
def test_reference_case(case):
    points = scan_points(case["generator"])
    assert_points(points, case)
    assert sum(1 for _ in range(points.size)) == case["size"]
    assert [d.size for d in points.dimensions] == case["shape"]
    assert [a for d in points.dimensions for a in d.axes] == case["axes"]


@pytest.mark.skipif(not CASES, reason=f"reference data {CASES_FILE} is absent")
@pytest.mark.parametrize("case", CASES, ids=[c["name"] for c in CASES])
def test_reference_case_to_json_round_trips(case):
    data = scan_points(case["generator"]).to_json()
    assert set(data) == {
        "axes",
        "size",
        "shape",
        "positions",
        "lower",
        "upper",
        "duration",
    }
    text = json.loads(json.dumps(data))
    assert_points_json = {k: text[k] for k in ("axes", "shape", "size")}
    assert assert_points_json == {k: case[k] for k in ("axes", "shape", "size")}
    for key in ("positions", "lower", "upper"):
        assert all(isinstance(v, float) for vs in text[key].values() for v in vs)
        assert_close(text[key], case[key])
    np.testing.assert_allclose(text["duration"], case["duration"], atol=TOL)


@pytest.mark.skipif(not CASES, reason=f"reference data {CASES_FILE} is absent")
def test_roi_rectangle_keeps_grid_shape_and_restarts_snake():
    case = next(c for c in CASES if c["name"] == "grid_rect_roi_snake")
    points = scan_points(case["generator"])
    assert points.dimensions == [Dimension(["y"], 2, False), Dimension(["x"], 2, True)]
    # The shrunk inner line runs forwards first, then backwards
    assert points.positions["x"].tolist() == [1.0, 2.0, 2.0, 1.0]


# -- further behaviour recorded from scanpointgenerator 3.1 -----------------

CIRCLE = {
    "typeid": ROI_EXCLUDER,
    "axes": ["x", "y"],
    "rois": [
        {
            "typeid": "scanpointgenerator:roi/CircularROI:1.0",
            "centre": [1, 1],
            "radius": 1,
        }
    ],
}


def test_circle_merges_dimensions_into_one():
    points = scan_points(
        compound(line("y", 0, 2, 3), line("x", 0, 2, 3, True), excluders=[CIRCLE])
    )
    assert_points(
        points,
        {
            "axes": ["y", "x"],
            "shape": [5],
            "positions": {"y": [0, 1, 1, 1, 2], "x": [1, 2, 1, 0, 1]},
            "lower": {"y": [0, 1, 1, 1, 2], "x": [0.5, 2.5, 1.5, 0.5, 0.5]},
            "upper": {"y": [0, 1, 1, 1, 2], "x": [1.5, 1.5, 0.5, -0.5, 1.5]},
        },
    )
    assert points.dimensions == [Dimension(["y", "x"], 5, False)]


def test_masked_alternating_dimension_reverses_on_next_outer_pass():
    points = scan_points(
        compound(
            line("z", 0, 1, 2),
            line("y", 0, 2, 3, True),
            line("x", 0, 2, 3, True),
            excluders=[CIRCLE],
        )
    )
    assert_points(
        points,
        {
            "axes": ["z", "y", "x"],
            "shape": [2, 5],
            "positions": {
                "z": [0, 0, 0, 0, 0, 1, 1, 1, 1, 1],
                "y": [0, 1, 1, 1, 2, 2, 1, 1, 1, 0],
                "x": [1, 2, 1, 0, 1, 1, 0, 1, 2, 1],
            },
            "lower": {
                "z": [0, 0, 0, 0, 0, 1, 1, 1, 1, 1],
                "y": [0, 1, 1, 1, 2, 2, 1, 1, 1, 0],
                "x": [0.5, 2.5, 1.5, 0.5, 0.5, 1.5, -0.5, 0.5, 1.5, 1.5],
            },
            "upper": {
                "z": [0, 0, 0, 0, 0, 1, 1, 1, 1, 1],
                "y": [0, 1, 1, 1, 2, 2, 1, 1, 1, 0],
                "x": [1.5, 1.5, 0.5, -0.5, 1.5, 0.5, 0.5, 1.5, 2.5, 0.5],
            },
        },
    )
    assert points.dimensions == [
        Dimension(["z"], 2, False),
        Dimension(["y", "x"], 5, True),
    ]


def test_concat_inner_snake_joins_bounds():
    concat = {
        "typeid": P + "ConcatGenerator:1.0",
        "generators": [line("x", 0, 1, 2), line("x", 2, 4, 3)],
        "alternate": True,
    }
    points = scan_points(compound(line("y", 0, 1, 2), concat, duration=0.2))
    assert_points(
        points,
        {
            "axes": ["y", "x"],
            "shape": [2, 5],
            "positions": {
                "y": [0] * 5 + [1] * 5,
                "x": [0, 1, 2, 3, 4, 4, 3, 2, 1, 0],
            },
            "lower": {
                "y": [0] * 5 + [1] * 5,
                "x": [-0.5, 0.5, 1.5, 2.5, 3.5, 4.5, 3.5, 2.5, 1.5, 0.5],
            },
            "upper": {
                "y": [0] * 5 + [1] * 5,
                "x": [0.5, 1.5, 2.5, 3.5, 4.5, 3.5, 2.5, 1.5, 0.5, -0.5],
            },
            "duration": [0.2] * 10,
        },
    )


def test_concat_with_a_gap_needs_continuous_false():
    concat = {
        "typeid": P + "ConcatGenerator:1.0",
        "generators": [line("x", 0, 1, 2), line("x", 3, 4, 2)],
    }
    with pytest.raises(
        GeneratorError, match=r"^generators\[0\]\.generators\[1\]: bounds"
    ):
        scan_points(compound(concat))
    points = scan_points(compound(concat, continuous=False))
    assert points.positions["x"].tolist() == [0, 1, 3, 4]
    assert points.lower["x"].tolist() == [0, 1, 3, 4]
    assert points.upper["x"].tolist() == [0, 1, 3, 4]


def test_not_continuous_has_no_bounds():
    points = scan_points(compound(line("x", 0, 2, 3), continuous=False))
    assert points.lower["x"].tolist() == [0, 1, 2]
    assert points.upper["x"].tolist() == [0, 1, 2]


def test_single_point_line_sits_midway_with_start_stop_bounds():
    points = scan_points(compound(line("x", 1, 3, 1)))
    assert points.positions["x"].tolist() == [2.0]
    assert points.lower["x"].tolist() == [1.0]
    assert points.upper["x"].tolist() == [3.0]


def test_static_generator_with_and_without_axis():
    static = {"typeid": P + "StaticPointGenerator:1.0", "size": 3}
    points = scan_points(compound(line("x", 0, 1, 2), static))
    assert points.axes == ["x"]
    assert points.shape == [2, 3]
    assert points.dimensions[1] == Dimension([], 3, False)
    assert points.positions["x"].tolist() == [0, 0, 0, 1, 1, 1]
    static_axis = dict(static, axes=["repeat"])
    points = scan_points(compound(static_axis, continuous=False))
    assert points.positions["repeat"].tolist() == [1, 2, 3]


def test_array_generator_bounds_interpolate():
    array = {
        "typeid": P + "ArrayGenerator:1.0",
        "axes": ["x"],
        "units": ["mm"],
        "points": [0.0, 1.0, 3.0],
    }
    points = scan_points(compound(array))
    assert points.positions["x"].tolist() == [0.0, 1.0, 3.0]
    assert points.lower["x"].tolist() == [-0.5, 0.5, 2.0]
    assert points.upper["x"].tolist() == [0.5, 2.0, 4.0]


ROI = "scanpointgenerator:roi/"


@pytest.mark.parametrize(
    ("roi", "inside"),
    [
        (
            {
                "typeid": ROI + "EllipticalROI:1.0",
                "centre": [1, 1],
                "semiaxes": [1, 0.5],
            },
            [(0, 1), (0.5, 1), (1, 0.5), (1, 1), (1, 1.5), (1.5, 1), (2, 1)],
        ),
        (
            {
                "typeid": ROI + "PolygonalROI:1.0",
                "points_x": [-0.1, 2.2, -0.1],
                "points_y": [-0.1, -0.1, 2.2],
            },
            [(x / 2, y / 2) for x in range(5) for y in range(5) if x + y <= 4],
        ),
        (
            {
                "typeid": ROI + "RectangularROI:1.0",
                "start": [1, 0],
                "width": 1,
                "height": 1,
                "angle": 0.5,
            },
            [(1, 0), (1, 0.5), (1, 1), (1.5, 0.5), (1.5, 1)],
        ),
        (
            # Radii are distances (scanpointgenerator 3.1 compares them with
            # the squared distance, which we do not reproduce)
            {
                "typeid": ROI + "SectorROI:1.0",
                "centre": [0, 0],
                "radii": [1, 2],
                "angles": [0, 1.5707963267948966],
            },
            [(0, 1), (0, 1.5), (0, 2), (0.5, 1), (0.5, 1.5), (1, 0), (1, 0.5)]
            + [(1, 1), (1, 1.5), (1.5, 0), (1.5, 0.5), (1.5, 1), (2, 0)],
        ),
        (
            {"typeid": ROI + "PointROI:1.0", "point": [1.5, 0.5]},
            [(1.5, 0.5)],
        ),
    ],
    ids=["ellipse", "polygon", "rotated_rectangle", "sector", "point"],
)
def test_rois(roi, inside):
    grid = compound(
        line("y", 0, 2, 5),
        line("x", 0, 2, 5),
        excluders=[{"typeid": ROI_EXCLUDER, "axes": ["x", "y"], "rois": [roi]}],
    )
    points = scan_points(grid)
    got = sorted(zip(points.positions["x"].tolist(), points.positions["y"].tolist()))
    assert got == sorted((float(x), float(y)) for x, y in inside)
    assert points.shape == [len(inside)]


def test_two_rois_are_a_union():
    rois = [
        {"typeid": "scanpointgenerator:roi/PointROI:1.0", "point": [0, 0]},
        {"typeid": "scanpointgenerator:roi/PointROI:1.0", "point": [2, 2]},
    ]
    points = scan_points(
        compound(
            line("y", 0, 2, 3),
            line("x", 0, 2, 3),
            excluders=[{"typeid": ROI_EXCLUDER, "axes": ["x", "y"], "rois": rois}],
        )
    )
    assert points.point(0) == {"y": 0.0, "x": 0.0}
    assert points.point(1) == {"y": 2.0, "x": 2.0}
    assert points.size == 2


def test_duration_absent_or_negative_is_none():
    data = compound(line("x", 0, 1, 2))
    del data["duration"]
    assert scan_points(data).duration is None
    assert scan_points(compound(line("x", 0, 1, 2), duration=-1)).duration is None
    assert scan_points(
        compound(line("x", 0, 1, 2), duration=0.3)
    ).duration.tolist() == [0.3, 0.3]


# -- scanspec ----------------------------------------------------------------


@pytest.mark.skipif(not CASES, reason=f"reference data {CASES_FILE} is absent")
def test_scanspec_snake_matches_the_generator_case():
    case = next(c for c in CASES if c["name"] == "snake_2d")
    spec = Fly(0.5 @ (Linspace("y", 1, 3, 2) * ~Linspace("x", 0, 0.5, 3)))
    points = scan_points(spec)
    assert_points(points, case)
    assert points.dimensions == [Dimension(["y"], 2, False), Dimension(["x"], 3, True)]


def test_scanspec_serialized_dict_equals_spec():
    spec = Fly(
        0.1
        @ (Linspace("z", 0, 1, 2) * ~Linspace("x", 0, 2, 3).zip(Linspace("y", 5, 7, 3)))
    )
    from_spec = scan_points(spec)
    from_dict = scan_points(dict(spec.serialize()))
    assert from_spec.to_json() == from_dict.to_json()
    assert from_spec.axes == ["z", "x", "y"]
    assert from_spec.shape == [2, 3]
    assert from_spec.positions["y"].tolist() == [5, 6, 7, 7, 6, 5]
    assert from_spec.lower["x"].tolist() == [-0.5, 0.5, 1.5, 2.5, 1.5, 0.5]


def test_scanspec_step_scan_without_duration():
    points = scan_points(Linspace("y", 0, 1, 2) * Linspace("x", 0, 1, 2))
    assert points.duration is None
    assert points.to_json()["duration"] is None
    for axis in points.axes:
        np.testing.assert_array_equal(points.lower[axis], points.positions[axis])
        np.testing.assert_array_equal(points.upper[axis], points.positions[axis])
    assert points.positions["x"].tolist() == [0, 1, 0, 1]


def test_scanspec_spiral_concat_and_static():
    spiral = scan_points(Fly(Spiral("x", 0, 10, 2, "y", 5)))
    assert spiral.axes == ["y", "x"]
    assert len(spiral.dimensions) == 1 and spiral.dimensions[0].axes == ["y", "x"]
    assert spiral.size == spiral.shape[0] > 10
    assert np.all(np.hypot(spiral.positions["x"], spiral.positions["y"] - 5) < 5)

    concat = scan_points(Concat(Linspace("x", 0, 1, 2), Linspace("x", 5, 6, 3)))
    assert concat.positions["x"].tolist() == [0, 1, 5, 5.5, 6]

    zipped = scan_points(Zip(Linspace("x", 0, 1, 3), Static("y", 4)))
    assert zipped.positions["y"].tolist() == [4, 4, 4]


def test_scanspec_from_yaml_file(tmp_path):
    spec = 0.25 @ Linspace("x", 0, 1, 3)
    import yaml

    file = tmp_path / "spec.yaml"
    file.write_text(yaml.safe_dump(dict(spec.serialize())))
    points = points_from_file(file)
    assert points.positions["x"].tolist() == [0, 0.5, 1]
    assert points.duration.tolist() == [0.25] * 3


def test_generator_from_json_and_yaml_files(tmp_path):
    import yaml

    data = compound(line("y", 0, 1, 2), line("x", 0, 1, 3, True))
    expected = scan_points(data).to_json()
    (tmp_path / "g.json").write_text(json.dumps(data))
    (tmp_path / "g.yml").write_text(yaml.safe_dump(data))
    assert points_from_file(tmp_path / "g.json").to_json() == expected
    assert points_from_file(str(tmp_path / "g.yml")).to_json() == expected
    # A configure-style wrapper is unwrapped
    (tmp_path / "w.json").write_text(json.dumps({"generator": data}))
    assert points_from_file(tmp_path / "w.json").to_json() == expected


# -- ScanPoints methods ------------------------------------------------------


def grid_y3_x2() -> ScanPoints:
    return scan_points(compound(line("y", 0, 2, 3), line("x", 0, 1, 2)))


def test_steps_per_run():
    points = grid_y3_x2()
    assert points.steps_per_run(["x"]) == 2
    assert points.steps_per_run(["x", "y"]) == 6
    assert points.steps_per_run(["y", "x"]) == 6
    assert points.steps_per_run(None) == 6
    assert points.steps_per_run([]) == 1


def test_steps_per_run_rejects_unknown_axis():
    with pytest.raises(ValueError, match="'z'"):
        grid_y3_x2().steps_per_run(["x", "z"])


def test_steps_per_run_rejects_outer_axis_without_inner():
    with pytest.raises(ValueError, match="'x'"):
        grid_y3_x2().steps_per_run(["y"])


def test_steps_per_run_rejects_half_a_merged_dimension():
    points = scan_points(
        compound(line("y", 0, 2, 3), line("x", 0, 2, 3), excluders=[CIRCLE])
    )
    with pytest.raises(ValueError, match="'y'"):
        points.steps_per_run(["x"])
    assert points.steps_per_run(["x", "y"]) == points.size == 5


def test_steps_per_run_with_static_repeats_inside():
    static = {"typeid": P + "StaticPointGenerator:1.0", "size": 4}
    points = scan_points(compound(line("y", 0, 2, 3), line("x", 0, 1, 2), static))
    assert points.steps_per_run(["x"]) == 8
    assert points.steps_per_run([]) == 1
    assert points.steps_per_run(["x", "y"]) == 24


def test_point_and_size():
    points = grid_y3_x2()
    assert points.size == 6
    assert points.point(0) == {"y": 0.0, "x": 0.0}
    assert points.point(3) == {"y": 1.0, "x": 1.0}
    assert points.point(-1) == {"y": 2.0, "x": 1.0}
    with pytest.raises(IndexError):
        points.point(6)

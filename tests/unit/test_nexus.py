"""The scan file's assembler (malcolm.io.nexus): raw files built by hand with
h5py as the device managers write them, a seek back included."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

from malcolm.io.nexus import DatasetRow, assemble, last_rows, rows_from_table


def test_last_rows_keeps_the_last_row_of_each_uniqueid():
    # points 1..4, then a seek back to point 2 (uid 3) re-does 3, 4; 0 is none
    uids = np.array([1, 2, 3, 0, 3, 4, 4, 9])
    rows, points = last_rows(uids, npoints=5)
    assert points.tolist() == [0, 1, 2, 3]
    assert rows.tolist() == [0, 1, 4, 6]


def write_raw(path, name, values, uids):
    with h5py.File(path, "w") as f:
        f.create_dataset(name, data=np.asarray(values))
        f.create_dataset("uid", data=np.asarray(uids).reshape(-1, 1, 1))


def det_row(rank=2):
    return DatasetRow("det.data", "scan-det.h5", "primary", rank, "/frames", "/uid")


@pytest.fixture
def raw(tmp_path):
    """A 2x3 grid: the detector did points 0..3, was sought back to point 2
    and did 2..5 again (frames carry 100 * uid + the time they were taken,
    so the later frame of a point is the larger); the motor's readbacks
    the same; the PandA lost point 5."""
    order = [1, 2, 3, 4, 3, 4, 5, 6]
    frames = np.stack(
        [np.full((2, 3), 100 * u + i, np.uint16) for i, u in enumerate(order)]
    )
    write_raw(tmp_path / "scan-det.h5", "frames", frames, order)
    x = np.array([10.0 * u + i / 100 for i, u in enumerate(order)])
    write_raw(tmp_path / "scan-motor.h5", "x", x, order)
    panda = [1, 2, 3, 4, 5]
    write_raw(tmp_path / "scan-panda.h5", "enc", np.array(panda) * 1.5, panda)
    return tmp_path


def rows():
    return [
        det_row(),
        DatasetRow("x.value", "scan-motor.h5", "position_value", 0, "/x", "/uid"),
        DatasetRow("panda.INENC1.VAL", "scan-panda.h5", "monitor", 0, "/enc", "/uid"),
    ]


def test_one_row_per_point_shaped_as_the_scan(raw):
    demands = {"y": np.repeat([0.0, 1.0], 3), "x": np.array([0, 1, 2, 2, 1, 0.0])}
    result = assemble(raw / "scan.nxs", raw, rows(), (2, 3), demands)
    assert result.problems == []
    with h5py.File(raw / "scan.nxs", "r") as f:
        frames = f["/entry/det/data"][()]
        assert frames.shape == (2, 3, 2, 3)
        # each point once, its last frame: uid 3 was taken at 4, 4 at 5
        assert frames[:, :, 0, 0].ravel().tolist() == [100, 201, 304, 405, 506, 607]
        assert f["/entry/x/value"][()].ravel() == pytest.approx(
            [10.0, 20.01, 30.04, 40.05, 50.06, 60.07]
        )
        assert f["/entry/x/value_set"][()].tolist() == [[0, 1, 2], [2, 1, 0]]
        enc = f["/entry/panda/INENC1.VAL"][()].ravel()
        assert enc[:5].tolist() == [1.5, 3.0, 4.5, 6.0, 7.5]
        assert np.isnan(enc[5])  # missing, not invented
        assert f["/entry/uniqueid"][()].tolist() == [[1, 2, 3], [4, 5, 6]]
        assert f["/entry"].attrs["NX_class"] == "NXentry"
        assert f["/entry/instrument"].attrs["NX_class"] == "NXinstrument"
        det = f["/entry/det"]
        assert det.attrs["NX_class"] == "NXdata"
        assert det.attrs["signal"] == "data"
        assert list(det.attrs["axes"]) == ["y_set", "x_set", ".", "."]
        assert det["x_set"][()].tolist() == [[0, 1, 2], [2, 1, 0]]
        assert f["/entry/x"].attrs["NX_class"] == "NXpositioner"
        assert f["/entry/panda"].attrs["NX_class"] == "NXcollection"
        assert f["/entry/instrument/det/data"].shape == (2, 3, 2, 3)
    assert result.points_present == {"det.data": 6, "x.value": 6, "panda.INENC1.VAL": 5}
    assert {r.path for r in result.rows} == {
        "/entry/det/data",
        "/entry/x/value",
        "/entry/panda/INENC1.VAL",
        "/entry/y/value_set",
        "/entry/x/value_set",
    }


def test_points_not_done_have_uniqueid_zero(tmp_path):
    # an aborted scan: 3 of 6 points
    write_raw(tmp_path / "scan-det.h5", "frames", np.ones((3, 2, 2)), [1, 2, 3])
    result = assemble(tmp_path / "s.nxs", tmp_path, [det_row()], (6,))
    assert result.points_present == {"det.data": 3}
    with h5py.File(tmp_path / "s.nxs", "r") as f:
        assert f["/entry/uniqueid"][()].tolist() == [1, 2, 3, 0, 0, 0]
        assert np.isnan(f["/entry/det/data"][3]).all()


def test_a_missing_file_is_named_and_the_rest_written(tmp_path):
    write_raw(tmp_path / "scan-det.h5", "frames", np.ones((2, 2, 2)), [1, 2])
    bad = DatasetRow("x.value", "nope.h5", "position_value", 0, "/x", "/uid")
    result = assemble(tmp_path / "s.nxs", tmp_path, [det_row(), bad], (2,))
    assert len(result.problems) == 1
    assert result.problems[0].startswith("x.value (nope.h5):")
    with h5py.File(tmp_path / "s.nxs", "r") as f:
        assert "x" not in f["/entry"]
        assert f["/entry/det/data"].shape == (2, 2, 2)
        # named in the file too, for whoever reads it
        assert list(f["/entry"].attrs["problems"]) == result.problems


def test_mismatched_lengths_are_named(tmp_path):
    with h5py.File(tmp_path / "scan-det.h5", "w") as f:
        f["frames"] = np.ones((3, 2, 2))
        f["uid"] = np.array([1, 2])
    result = assemble(tmp_path / "s.nxs", tmp_path, [det_row()], (3,))
    assert "3 rows but /uid has 2" in result.problems[0]


def test_no_temporary_file_is_left(tmp_path):
    write_raw(tmp_path / "scan-det.h5", "frames", np.ones((1, 2, 2)), [1])
    assemble(tmp_path / "s.nxs", tmp_path, [det_row()], (1,))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.nxs", "scan-det.h5"]


def test_rows_from_table_names_a_missing_column():
    table = {
        "name": ["det.data"],
        "filename": ["d.h5"],
        "type": ["primary"],
        "rank": [2],
        "path": ["/d"],
        "uniqueid": ["/u"],
    }
    assert rows_from_table(table) == [
        DatasetRow("det.data", "d.h5", "primary", 2, "/d", "/u")
    ]
    del table["uniqueid"]
    with pytest.raises(ValueError, match="uniqueid"):
        rows_from_table(table)

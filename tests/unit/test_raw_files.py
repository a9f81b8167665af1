"""The device managers' raw files as configure makes them: a new, empty
file replacing what was there (removed, not truncated by HDF5), with the
layout the file assembler reads."""

from __future__ import annotations

import h5py
import numpy as np

from malcolm.parts.datasets import new_h5_file
from malcolm.parts.motion_file import MotionFile
from malcolm.parts.zebra2_scan_file import create_scan_file, uniqueids


def test_a_new_file_replaces_the_old_one_whose_reader_keeps_it(tmp_path):
    path = tmp_path / "sub" / "raw.h5"
    with new_h5_file(path) as f:  # the directory is made
        f["old"] = np.arange(5)
    reader = h5py.File(path, "r")
    try:
        with new_h5_file(path) as f:
            f["new"] = np.arange(3)
        # a reader of the old file still reads it whole
        assert list(reader["old"][()]) == [0, 1, 2, 3, 4]
    finally:
        reader.close()
    with h5py.File(path, "r") as f:
        assert list(f) == ["new"]


def test_the_motion_file_has_its_datasets_empty_and_appendable(tmp_path):
    path = tmp_path / "m.h5"
    path.write_bytes(b"not an HDF5 file")  # replaced, whatever it was
    motion = MotionFile(str(path), ["x", "y"])
    motion.create()
    with h5py.File(path, "r") as f:
        for name in ("entry/uniqueid", "entry/x/value_set", "entry/x/value",
                     "entry/y/value_set", "entry/y/value"):  # fmt: skip
            ds = f[name]
            assert ds.shape == (0,) and ds.maxshape == (None,)
            assert ds.chunks == (1024,)
        assert f["entry/uniqueid"].dtype == np.int32
        assert f["entry/x/value"].dtype == np.float64
    uid = np.array([1, 2], np.int32)
    motion.append(uid, {"x": uid * 1.0, "y": uid * 2.0}, {"x": uid, "y": uid})
    motion.create()  # configured again: empty again
    with h5py.File(path, "r") as f:
        assert f["entry/uniqueid"].shape == (0,)


def test_the_zebra_file_replaces_the_last_scans(tmp_path):
    path = tmp_path / "z.h5"
    create_scan_file(path, {"scan": "one"})
    with h5py.File(path, "a") as f:
        f["uniqueid"].resize((2,))
        f["uniqueid"][:] = [1, 2]
    assert list(uniqueids(path)) == [1, 2]
    create_scan_file(path, {"scan": "two"})
    assert list(uniqueids(path)) == []
    with h5py.File(path, "r") as f:
        assert f.attrs["scan"] == "two"

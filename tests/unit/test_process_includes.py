"""An include that names a directory says so (not "no such file")."""

from __future__ import annotations

import pytest

from malcolm.config import ConfigError, load_process_file


def test_including_a_directory_is_named_as_such(tmp_path):
    (tmp_path / "common").mkdir()
    process = tmp_path / "p.yaml"
    process.write_text("define.String:\n  name: a\n  value: b\ninclude: common\n")
    with pytest.raises(ConfigError) as info:
        load_process_file(process)
    assert str(info.value) == (
        f"{process}:4: cannot include a directory: {tmp_path / 'common'}"
    )


def test_including_a_missing_file_is_named_as_such(tmp_path):
    process = tmp_path / "p.yaml"
    process.write_text("include: [gone.yaml]\n")
    with pytest.raises(ConfigError) as info:
        load_process_file(process)
    assert str(info.value) == f"{process}:1: no such file: {tmp_path / 'gone.yaml'}"

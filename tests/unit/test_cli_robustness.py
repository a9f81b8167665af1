"""Adversarial but plausible inputs: a named problem, never a traceback."""

import pytest

from malcolm.cli import main


def run_cli(capsys, *argv):
    status = main(list(argv))
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err
    assert "internal error" not in out + err
    return status, out + err


def test_a_huge_int_for_a_float_is_a_problem_at_its_line(tmp_path, capsys):
    f = tmp_path / "p.yaml"
    f.write_text("define.Float:\n    name: f\n    value: " + "9" * 400 + "\n")
    status, text = run_cli(capsys, "check", str(f))
    assert status == 1
    assert f"{f}:3:" in text and "Float" in text


def test_an_empty_model_is_a_problem(tmp_path, capsys):
    f = tmp_path / "m.yaml"
    f.write_text("")
    status, text = run_cli(capsys, "graph", str(f))
    assert status == 1 and "empty" in text


@pytest.mark.parametrize("suffix", [".json", ".yaml"])
def test_deeply_nested_points_file_is_a_problem(tmp_path, capsys, suffix):
    f = tmp_path / f"g{suffix}"
    f.write_text("[" * 100000 + "]" * 100000)
    status, text = run_cli(capsys, "points", str(f))
    assert status == 1 and "nested too deeply" in text


def test_a_symlink_loop_include_is_a_problem(tmp_path, capsys):
    (tmp_path / "a.yaml").symlink_to(tmp_path / "b.yaml")
    (tmp_path / "b.yaml").symlink_to(tmp_path / "a.yaml")
    f = tmp_path / "p.yaml"
    f.write_text("include: a.yaml\n")
    status, text = run_cli(capsys, "check", str(f))
    assert status == 1 and f"{f}:1: cannot read include" in text


@pytest.mark.parametrize("mri", ["../../esc", "A B", "x/y"])
def test_an_mri_that_could_escape_or_confuse_is_refused(tmp_path, capsys, mri):
    f = tmp_path / "p.yaml"
    f.write_text(f"block.demo.Hello:\n    mri: '{mri}'\n")
    status, text = run_cli(capsys, "check", str(f))
    assert status == 1 and f"{f}:2:" in text and "may hold only" in text


def test_a_controller_keyword_of_the_wrong_type_is_a_problem_at_its_line(
    tmp_path, capsys
):
    lab = tmp_path / "lab"
    lab.mkdir()
    f = lab / "Box.yaml"
    f.write_text(
        "controller.RunnableController:\n    description: m\n    phase_timeout: abc\n"
    )
    status, text = run_cli(capsys, "check", str(f))
    assert status == 1
    assert (
        f"{f}:3: controller.RunnableController: 'phase_timeout' must be a number"
        in (text)
    )


def test_check_reads_a_process_file_with_a_bom_and_refuses_an_empty_name(
    tmp_path, capsys
):
    f = tmp_path / "p.yaml"
    f.write_bytes(b"\xef\xbb\xbfblock.demo.Hello:\n    mri: X\n")
    assert run_cli(capsys, "check", str(f))[0] == 0
    status, text = run_cli(capsys, "check", "")
    assert status == 1 and "an empty file name" in text

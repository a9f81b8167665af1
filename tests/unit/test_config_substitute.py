"""{name} substitution into nested values and keys."""

import pytest

from malcolm.config.errors import ConfigError
from malcolm.config.substitute import references, substitute, substitute_section
from malcolm.config.yamlsections import parse_sections

NAMES = {"prefix": "BL18I", "count": 3, "ratio": 0.5, "on": True, "unset": None}


def test_strings_are_interpolated():
    assert substitute("{prefix}:Exposure", NAMES, file="f") == "BL18I:Exposure"
    assert substitute("{prefix}-{count}", NAMES, file="f") == "BL18I-3"


def test_whole_string_keeps_the_type():
    assert substitute("{count}", NAMES, file="f") == 3
    assert substitute("{ratio}", NAMES, file="f") == 0.5
    assert substitute("{on}", NAMES, file="f") is True
    assert substitute("{unset}", NAMES, file="f") is None


def test_nested_values_and_keys():
    value = {
        "pv": "{prefix}:X",
        "rows": [{"{prefix}_col": "{count}"}, ["{ratio}", "a{count}b"]],
        "n": 7,
    }
    assert substitute(value, NAMES, file="f") == {
        "pv": "BL18I:X",
        "rows": [{"BL18I_col": 3}, [0.5, "a3b"]],
        "n": 7,
    }


def test_keys_are_always_text():
    assert substitute({"{count}": 1}, NAMES, file="f") == {"3": 1}


def test_escapes_and_stray_braces():
    assert substitute("{{prefix}}", NAMES, file="f") == "{prefix}"
    assert substitute("{{{prefix}}}", NAMES, file="f") == "{BL18I}"
    assert substitute("a { b } {1} {", NAMES, file="f") == "a { b } {1} {"


def test_unknown_name_is_an_error_at_the_values_line():
    (section,) = parse_sections(
        "parts.P:\n  a: ok\n  b:\n    - x\n    - {prefx}:Y\n", "d.yaml"
    )
    with pytest.raises(ConfigError) as info:
        substitute_section(section, NAMES)
    assert str(info.value) == (
        "d.yaml:5: unknown parameter '{prefx}' in 'b.1' (did you mean 'prefix'?)"
    )


def test_no_value_inside_a_longer_string_is_an_error():
    with pytest.raises(ConfigError, match=r"^f:4: parameter 'unset' has no value"):
        substitute("x{unset}", NAMES, file="f", line=4)


def test_every_problem_is_reported():
    with pytest.raises(ConfigError) as info:
        substitute(["{a}", "{b}"], NAMES, file="f", line=lambda path: 10 + path[0])
    assert [str(p) for p in info.value.problems] == [
        "f:10: unknown parameter '{a}' in '0'",
        "f:11: unknown parameter '{b}' in '1'",
    ]


def test_section_lines_follow_renamed_keys():
    (section,) = parse_sections("parts.P:\n  t:\n    '{prefix}_a':\n      - 1\n")
    result = substitute_section(section, NAMES)
    assert result.params == {"t": {"BL18I_a": [1]}}
    assert result.line_of(("t", "BL18I_a", 0)) == 4
    assert result.param_lines == {"t": 2}


def test_references():
    assert references({"{a}": ["x{b}", "{{c}}"], "d": 1}) == {"a", "b"}

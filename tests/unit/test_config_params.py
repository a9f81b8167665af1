"""init.* declarations and checking the values given for them."""

import pytest

from malcolm.config.errors import ConfigError
from malcolm.config.params import InitParam, param_from_section, resolve_params
from malcolm.config.yamlsections import parse_sections

DECLARED = [
    InitParam("prefix", "String", "PV Prefix", required=True, file="d.yaml", line=1),
    InitParam("count", "Int", default=3, file="d.yaml", line=5),
    InitParam("exposure", "Float", default=0.1, file="d.yaml", line=8),
    InitParam("enabled", "Boolean", default=False, file="d.yaml", line=11),
    InitParam("det", "ADCore.DetectorDriver", file="d.yaml", line=14),
]


def declare(text):
    (section,) = parse_sections(text, "d.yaml")
    return param_from_section(section)


def test_declarations():
    param = declare(
        "init.String:\n  name: prefix\n  description: PV\n  required: true\n"
    )
    assert param == InitParam("prefix", "String", "PV", True, None, "d.yaml", 1)
    assert not param.is_block_reference
    param = declare("init.Float:\n  name: t\n  default: 1\n")
    assert param.default == 1.0 and isinstance(param.default, float)
    param = declare("init.ADCore.DetectorDriver:\n  name: det\n")
    assert param.is_block_reference and param.required is False


@pytest.mark.parametrize(
    "text, line, message",
    [
        ("init.Strng:\n  name: x\n", 1, "did you mean 'init.String'?"),
        ("init.Int:\n  description: no name\n", 1, "init.Int needs a 'name'"),
        ("init.Int:\n  name: 1x\n", 2, "parameter name '1x' must be"),
        ("init.Int:\n  name: x\n  default: abc\n", 3, "default 'abc' is not an Int"),
        ("init.Int:\n  name: x\n  required: maybe\n", 3, "required must be true"),
        ("init.Int:\n  name: x\n  defualt: 1\n", 3, "did you mean 'default'?"),
        ("init.String:\n  name: mri\n", 2, "'mri' is reserved"),
    ],
)
def test_bad_declarations(text, line, message):
    with pytest.raises(ConfigError) as info:
        declare(text)
    assert f"d.yaml:{line}: " in str(info.value)
    assert message in str(info.value)


def test_defaults_applied_and_types_kept():
    values = resolve_params(DECLARED, {"prefix": "BL18I", "exposure": 2}, "p.yaml")
    assert values == {
        "prefix": "BL18I",
        "count": 3,
        "exposure": 2.0,
        "enabled": False,
        "det": None,
    }
    assert isinstance(values["exposure"], float)


def test_missing_required_reported_at_the_giving_line():
    with pytest.raises(ConfigError) as info:
        resolve_params(DECLARED, {}, "p.yaml", line=7)
    assert str(info.value) == (
        "p.yaml:7: missing required parameter 'prefix' (PV Prefix)"
    )


def test_missing_required_without_a_line_points_at_the_declaration():
    with pytest.raises(ConfigError, match=r"^d\.yaml:1: missing required"):
        resolve_params(DECLARED, {}, "p.yaml")


def test_unknown_and_wrongly_typed_values_all_reported():
    given = {"prefix": "X", "cuont": 1, "count": "abc", "enabled": 1, "det": ""}
    lines = {"prefix": 2, "cuont": 3, "count": 4, "enabled": 5, "det": 6}
    with pytest.raises(ConfigError) as info:
        resolve_params(
            DECLARED, given, "p.yaml", line=1, given_lines=lines, context="demo.X"
        )
    assert str(info.value).splitlines() == [
        "p.yaml:3: demo.X: unknown parameter 'cuont' (did you mean 'count'?) "
        "(parameters: prefix, count, exposure, enabled, det)",
        "p.yaml:4: demo.X: parameter 'count' must be an Int, not 'abc'",
        "p.yaml:5: demo.X: parameter 'enabled' must be a Boolean, not 1",
        "p.yaml:6: demo.X: parameter 'det' must be an mri of a "
        "ADCore.DetectorDriver block (text), not ''",
    ]


@pytest.mark.parametrize(
    "name, value, ok",
    [
        ("count", 5, True),
        ("count", True, False),
        ("count", 5.0, False),
        ("exposure", 5, True),
        ("exposure", False, False),
        ("exposure", "0.1", False),
        ("enabled", True, True),
        ("enabled", "yes", False),
        ("det", "BL18I:DET", True),
        ("det", 5, False),
        ("prefix", 5, False),
    ],
)
def test_type_checks(name, value, ok):
    given = {"prefix": "X", name: value}
    if ok:
        assert resolve_params(DECLARED, given, "p.yaml")[name] == value
    else:
        with pytest.raises(ConfigError, match=f"parameter '{name}' must be"):
            resolve_params(DECLARED, given, "p.yaml")

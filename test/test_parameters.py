"""The shadow's parameters: one table (types, units, ranges), strict in replay and in the node alike."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from bridge_shadow.errors import ConfigError
from bridge_shadow.estimate import ShadowConfig, load_config
from bridge_shadow.estimate.parameters.specs import SPECS, constraint_text, kind_of, parameter_docs, yaml_unit

FIELDS = {f.name: f for f in dataclasses.fields(ShadowConfig)}


def test_every_parameter_has_one_spec_and_a_documented_unit(root: Path) -> None:
    assert set(SPECS) == set(FIELDS)  # a new ShadowConfig field needs its one entry in SPECS
    docs = parameter_docs(root / "config" / "shadow.yaml")
    assert set(docs) == set(FIELDS)  # and its documented entry in config/shadow.yaml
    for name, spec in SPECS.items():
        assert docs[name], name
        if spec.unit:  # the unit in the table is the one the YAML comment states
            assert yaml_unit(docs[name]) == spec.unit, name
        if spec.choices:  # a choice parameter's default is one of its choices
            assert FIELDS[name].default in spec.choices, name


BAD = [
    ("window_s", True),  # `true` is not 1 s
    ("window_s", "60"),
    ("window_s", math.inf),
    ("window_s", math.nan),
    ("window_s", 0.0),
    ("window_min_samples", 2.7),  # 2.7 is not 2
    ("window_min_samples", 3.0),  # an integer parameter takes integers
    ("window_min_samples", True),
    ("window_min_samples", 0),
    ("noise_floor", 1),
    ("noise_floor", "true"),
    ("prior_sigma_m", [3e-4]),
    ("prior_sigma_m", [3e-4, True]),
    ("prior_sigma_m", [math.inf, 3e-4]),
    ("prior_sigma_m", "3e-4"),
    ("prior_sigma_m", [0.0, 3e-4]),
    ("smoothing", "magic"),
    ("smoothing", None),
    ("noise_phi_max", 1.0),
    ("mahalanobis_probability", 0.0),
    ("diagnostics_period_s", 0.0),  # used to spin a core at 100 %
    ("diagnostics_period_s", -1.0),
    ("checkpoint_period_s", 0.0),
    ("checkpoint_unusable", "ignore"),
    ("force_max_n", math.inf),
    ("clock_jump_s", -math.inf),
    ("topic_frc_01", 5),
]


@pytest.mark.parametrize(("name", "value"), BAD, ids=[f"{n}={v!r}" for n, v in BAD])
def test_bad_values_are_refused_naming_the_parameter(name: str, value: object) -> None:
    with pytest.raises(ConfigError, match=rf"^shadow parameters: {name} must be ") as err:
        ShadowConfig.from_params({name: value})
    assert "\n" not in str(err.value)
    with pytest.raises(ConfigError):
        ShadowConfig(**{name: value})  # from Python as from a file


def test_cross_field_rules_and_unknown_names() -> None:
    with pytest.raises(ConfigError, match="temp_max_c must exceed temp_min_c"):
        ShadowConfig(temp_min_c=20.0, temp_max_c=10.0)
    # both named with their values (it said "gap_s must be at least window_s" and no more)
    with pytest.raises(ConfigError, match=r"gap_s must be at least window_s \(now gap_s 30, window_s 60\)"):
        ShadowConfig(gap_s=30.0, window_s=60.0)
    with pytest.raises(ConfigError, match=r"unknown key 'windw_s' \(did you mean window_s\?\)"):
        ShadowConfig.from_params({"windw_s": 60.0})


def test_a_parameter_given_twice_in_a_file_is_refused_where_it_is(tmp_path: Path) -> None:
    """YAML forbids a key twice; PyYAML kept the second value without a word (window_s 60, not 30)."""
    path = _params_file(tmp_path, "    window_s: 30.0\n    warmup_windows: 5\n    window_s: 60.0\n")
    with pytest.raises(ConfigError, match=r"line 5, column 5: key 'window_s' given twice"):
        load_config(path)
    merged = _params_file(tmp_path, "    prior_sigma_m: &s [0.01, 0.01]\n    window_s: 30.0\n")
    assert load_config(merged).window_s == 30.0  # anchors and the rest as before


def test_an_integer_is_taken_for_a_real_and_kept_as_one() -> None:
    cfg = ShadowConfig.from_params({"window_s": 60, "prior_sigma_m": [1, 0.5], "window_min_samples": 4})
    assert cfg.window_s == 60.0 and type(cfg.window_s) is float
    assert cfg.prior_sigma_m == [1.0, 0.5] and all(type(v) is float for v in cfg.prior_sigma_m)
    assert type(cfg.window_min_samples) is int
    assert constraint_text("window_s", kind_of(FIELDS["window_s"])) == "a finite number in (0, 86400]"
    assert constraint_text("noise_phi_max", "float") == "a finite number in [0, 1)"


def _params_file(tmp_path: Path, body: str) -> Path:
    path = tmp_path / "p.yaml"
    path.write_text("bridge_shadow:\n  ros__parameters:\n" + body)
    return path


def test_parameter_files_read_like_ros_reads_them(tmp_path: Path) -> None:
    # PyYAML alone reads 5.0e6 and 1e-4 as strings; rcl (the node) reads them as numbers
    cfg = load_config(_params_file(tmp_path, "    force_max_n: 5.0e6\n    prior_sigma_m: [1e-4, 2E-4]\n"))
    assert cfg.force_max_n == 5.0e6 and cfg.prior_sigma_m == [1e-4, 2e-4]
    with pytest.raises(ConfigError, match=r"window_s must be a finite number in \(0, 86400\], not inf"):
        load_config(_params_file(tmp_path, "    window_s: .inf\n"))
    with pytest.raises(ConfigError, match=r"window_s must be a finite number in \(0, 86400\], not true"):
        load_config(_params_file(tmp_path, "    window_s: true\n"))
    with pytest.raises(ConfigError, match=r"not valid YAML at line 4, column 1: ") as err:
        load_config(_params_file(tmp_path, "    window_s: [\n"))
    assert "\n" not in str(err.value)
    with pytest.raises(ConfigError, match="is a directory"):
        load_config(tmp_path)
    (tmp_path / "b.yaml").write_bytes(bytes(range(128, 256)))
    with pytest.raises(ConfigError, match="cannot read the parameter file"):
        load_config(tmp_path / "b.yaml")


# -- the node: the same table gives its descriptors and its set-parameters callback -------------


@pytest.fixture
def node_factory():
    rclpy = pytest.importorskip("rclpy")
    from bridge_shadow.ros.node import ShadowNode

    context = rclpy.Context()
    rclpy.init(context=context)
    nodes = []

    def make(overrides=()):
        node = ShadowNode(context=context, parameter_overrides=list(overrides))
        nodes.append(node)
        return node

    yield make
    for node in nodes:
        node.destroy_node()
    rclpy.try_shutdown(context=context)


@pytest.mark.ros
def test_node_descriptors_come_from_the_table(node_factory) -> None:
    from rcl_interfaces.msg import ParameterType

    node = node_factory()
    types = {
        "bool": ParameterType.PARAMETER_BOOL,
        "int": ParameterType.PARAMETER_INTEGER,
        "float": ParameterType.PARAMETER_DOUBLE,
        "str": ParameterType.PARAMETER_STRING,
        "float_pair": ParameterType.PARAMETER_DOUBLE_ARRAY,
    }
    for name, f in FIELDS.items():
        d = node.describe_parameter(name)
        kind = kind_of(f)
        assert d.type == types[kind], name
        assert d.read_only is not SPECS[name].live, name
        assert d.additional_constraints == constraint_text(name, kind), name
        if SPECS[name].unit:
            assert f"[{SPECS[name].unit}]" in d.description, name
    d = node.describe_parameter("noise_phi_max")
    assert (d.floating_point_range[0].from_value, d.floating_point_range[0].to_value) == (0.0, 1.0)


@pytest.mark.ros
def test_node_refuses_bad_values_with_a_reason_and_applies_good_ones(node_factory) -> None:
    from rclpy.parameter import Parameter

    node = node_factory()
    (result,) = node.set_parameters([Parameter("diagnostics_period_s", value=0.0)])
    assert not result.successful
    assert "diagnostics_period_s must be a finite number in [0.01, 86400]" in result.reason
    (result,) = node.set_parameters([Parameter("diagnostics_period_s", value=True)])
    assert not result.successful and "not true" in result.reason
    (result,) = node.set_parameters([Parameter("window_s", value=30.0)])
    assert not result.successful and "read-only" in result.reason
    assert node.config.window_s == 60.0
    (result,) = node.set_parameters([Parameter("use_sim_time", value=False)])  # rclpy's own: not ours
    assert result.successful
    (result,) = node.set_parameters([Parameter("diagnostics_period_s", value=2)])  # an int for a real
    assert result.successful
    assert node.config.diagnostics_period_s == 2.0
    assert node._diag_timer.timer_period_ns == 2 * 10**9


@pytest.mark.ros
@pytest.mark.parametrize(
    ("override", "message"),
    [
        (("windw_s", 60.0), "unknown key 'windw_s' (did you mean window_s?)"),
        (("window_s", True), "window_s must be a finite number in (0, 86400], not true"),
        (("window_min_samples", 2.7), "window_min_samples must be an integer in [1, 86400000], not 2.7"),
        (("window_s", math.inf), "window_s must be a finite number in (0, 86400], not inf"),
        (("diagnostics_period_s", -1.0), "diagnostics_period_s must be a finite number in [0.01, 86400]"),
    ],
)
def test_node_start_up_parameters_are_as_strict_as_replay(node_factory, override, message) -> None:
    from rclpy.parameter import Parameter

    with pytest.raises(ConfigError) as err:
        node_factory([Parameter(override[0], value=override[1])])
    assert message in str(err.value)


def test_spline_lambda_at_its_upper_end_fits_a_straight_line() -> None:
    """Why ``spline_lambda`` stops at 1e12 C^3: there the curve is a line; more would change nothing."""
    from test_estimate_pipeline import small_config, synthetic

    from bridge_shadow.estimate import Shadow
    from bridge_shadow.model.surrogate_file import placeholder_surrogate

    high = SPECS["spline_lambda"].high
    shadow = Shadow(small_config(smoothing="fixed", spline_lambda=high), placeholder_surrogate())
    shadow.run(synthetic(minutes=40, rate=1))  # forces follow the air at 300 / 80 N/K
    t = np.linspace(0.0, 20.0, 81)  # the knot range of small_config
    g = shadow.compensation.curve(shadow.fit, np.c_[t, t])
    for c in range(2):
        line = np.polyval(np.polyfit(t, g[:, c], 1), t)
        assert np.abs(g[:, c] - line).max() < 1e-9 * np.ptp(g[:, c])
    with pytest.raises(ConfigError, match="spline_lambda must be"):
        ShadowConfig(smoothing="fixed", spline_lambda=10 * high)

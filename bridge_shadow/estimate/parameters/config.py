"""Parameters of the online shadow: ``config/shadow.yaml`` loaded from plain Python.

The file is also the ROS node's parameter file, so its layout is
``bridge_shadow: ros__parameters: {name: value}`` with flat names (robot_localization style).
Every parameter is documented in the YAML file with its unit and default; the defaults here are
the same values, so an empty file gives the paper's set-up.
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from bridge_shadow.contract import (
    CHANNELS,
    COMPENSATED_TOPICS,
    COVARIANCE_TOPIC,
    DIAGNOSTICS_TOPIC,
    FORCE_TOPICS,
    MEAN_TOPIC,
    NODE_NAME,
    TEMPERATURE_FRAME,
    TEMPERATURE_TOPIC,
)
from bridge_shadow.errors import ConfigError
from bridge_shadow.estimate.parameters.specs import check_value, kind_of
from bridge_shadow.fileio import SAFE_LOADER, yaml_problem
from bridge_shadow.keys import check_keys
from bridge_shadow.paths import config_file

__all__ = ["ShadowConfig", "load_config", "read_params_file"]

#: The topic parameters (validated together in ``ShadowConfig.validate``).
_TOPIC_FIELDS = (
    "topic_frc_01",
    "topic_frc_02",
    "topic_air_temperature",
    "topic_mean",
    "topic_covariance",
    "topic_compensated_frc_01",
    "topic_compensated_frc_02",
)


class _Loader(SAFE_LOADER):  # type: ignore[misc]
    """PyYAML's safe loader with YAML 1.2 floats, as the ROS parameter parser reads them.

    PyYAML (YAML 1.1) reads ``5.0e6`` and ``1e-4`` as strings; rcl reads them as doubles, so the
    same file would mean different things to the node and to ``replay --params``.
    """


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(
        r"""^(?:[-+]?[0-9][0-9_]*\.[0-9_]*(?:[eE][-+]?[0-9]+)?
        |[-+]?[0-9][0-9_]*[eE][-+]?[0-9]+
        |[-+]?\.[0-9][0-9_]*(?:[eE][-+]?[0-9]+)?
        |[-+]?\.(?:inf|Inf|INF)
        |\.(?:nan|NaN|NAN))$""",
        re.VERBOSE,
    ),
    list("-+0123456789."),
)

#: A ROS topic name: absolute or relative, tokens of letters, digits and underscores.
_TOPIC_NAME = re.compile(r"^~?/?[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*$")


@dataclass
class ShadowConfig:
    """All parameters of the shadow pipeline (SI units; see ``config/shadow.yaml``)."""

    # alignment and aggregation
    window_s: float = 60.0
    window_min_samples: int = 3
    temperature_match: str = "linear"
    temperature_stale_s: float = 120.0
    topic_timeout_s: float = 30.0
    # traffic screen of short records (estimate/inputs/traffic.py)
    traffic_hold_s: float = 1800.0
    traffic_threshold_n: float = 300.0
    traffic_margin_s: float = 10.0
    traffic_vehicle_max_n: float = 30000.0
    # temperature compensation (fitted jointly with the settlement levels)
    smoothing: str = "reml"
    spline_lambda: float = 10.0
    spline_t_min_c: float = -20.0
    spline_t_max_c: float = 45.0
    spline_segments: int = 13
    thermal_prior_sd_n_per_k: float = 500.0
    sun_gradient: bool = True
    sun_gradient_prior_mean_k: float = 0.0
    sun_gradient_prior_sd_k: float = 6.75
    sun_gradient_min_bayes_factor: float = 3.0
    sun_gradient_fit: str = "average"
    relaxation_phi0: float = 0.663
    relaxation_horizon_s: float = 3600.0
    warmup_windows: int = 10
    refit_windows: int = 60
    lambda_reselect_growth: float = 1.25
    # settlement prior and process noise
    prior_sigma_m: list[float] = field(default_factory=lambda: [0.0, 0.0])
    prior_rule: str = "one_bearing"
    process_noise_m2_per_s: list[float] = field(default_factory=lambda: [0.0, 0.0])
    drift_block_s: float = 7200.0
    # measurement noise
    noise_sigma_n: list[float] = field(default_factory=lambda: [60.4, 82.7])
    systematic_sigma_n: list[float] = field(default_factory=lambda: [0.0, 0.0])
    noise_mode: str = "adaptive"
    noise_phi_max: float = 0.999
    noise_floor: bool = True
    # settlement events (GLR step detector)
    event_detection: bool = True
    event_trigger_probability: float = 0.999
    event_probability: float = 0.999999
    event_confirm_windows: int = 4
    event_max_pending: int = 15
    event_jump_rule: str = "both"
    gap_s: float = 600.0
    change_prior_probability: float = 0.5
    change_confirm_probability: float = 0.999
    # gating
    force_min_n: float = 1.0
    force_max_n: float = 5.0e6
    temp_min_c: float = -60.0
    temp_max_c: float = 70.0
    mahalanobis_probability: float = 0.999999
    clock_jump_s: float = 3600.0
    clock_jump_confirm: int = 2
    check_frame_id: bool = True
    temperature_frame_id: str = TEMPERATURE_FRAME
    # checkpoint
    checkpoint_path: str = ""
    checkpoint_period_s: float = 600.0
    checkpoint_unusable: str = "stop"
    # model
    surrogate_path: str = ""
    # node-only parameters (used by bridge_shadow.ros)
    qos_depth: int = 1000
    diagnostics_period_s: float = 1.0
    # topics (defaults: the contract); replay reads a bag's inputs under the same names
    topic_frc_01: str = FORCE_TOPICS["frc_01"]
    topic_frc_02: str = FORCE_TOPICS["frc_02"]
    topic_air_temperature: str = TEMPERATURE_TOPIC
    topic_mean: str = MEAN_TOPIC
    topic_covariance: str = COVARIANCE_TOPIC
    topic_compensated_frc_01: str = COMPENSATED_TOPICS["frc_01"]
    topic_compensated_frc_02: str = COMPENSATED_TOPICS["frc_02"]

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        """Check every value against its spec (``parameters.specs.SPECS``) and the cross-field rules.

        Values are normalized in place (an integer given for a real becomes a float); the first
        problem raises ConfigError with one line naming the parameter, what it must be and what
        it got.
        """
        for f in dataclasses.fields(self):
            try:
                value = check_value(f.name, getattr(self, f.name), kind_of(f))
            except ConfigError as err:
                raise ConfigError(f"shadow parameters: {err}") from None
            object.__setattr__(self, f.name, value)

        def need(cond: bool, msg: str) -> None:
            if not cond:
                raise ConfigError(f"shadow parameters: {msg}")

        def pair(a: str, b: str, rule: str) -> str:  # a rule between two: name both, with values
            return f"{a} must {rule} {b} (now {a} {getattr(self, a):g}, {b} {getattr(self, b):g})"

        need(self.spline_t_max_c > self.spline_t_min_c, pair("spline_t_max_c", "spline_t_min_c", "exceed"))
        need(self.force_max_n > self.force_min_n, pair("force_max_n", "force_min_n", "exceed"))
        need(self.temp_max_c > self.temp_min_c, pair("temp_max_c", "temp_min_c", "exceed"))
        need(
            min(self.prior_sigma_m) > 0 or max(self.prior_sigma_m) == 0,
            "prior_sigma_m must be > 0, or [0, 0] for the paper's rule (prior_rule)",
        )
        need(self.drift_block_s >= self.window_s, pair("drift_block_s", "window_s", "be at least"))
        need(
            self.event_max_pending > self.event_confirm_windows,
            pair("event_max_pending", "event_confirm_windows", "exceed"),
        )
        need(self.gap_s >= self.window_s, pair("gap_s", "window_s", "be at least"))
        topics = [*self.input_topics(), *self.output_topics().values()]
        for name in _TOPIC_FIELDS:
            value = getattr(self, name)
            need(bool(_TOPIC_NAME.match(value)), f"{name}: {value!r} is not a valid ROS topic name")
        need(len(set(topics)) == len(topics), "the input and output topics must all be different")

    def input_topics(self) -> tuple[str, str, str]:
        """Input topic names in the node's order: frc_01, frc_02, air temperature."""
        return (self.topic_frc_01, self.topic_frc_02, self.topic_air_temperature)

    def output_topics(self) -> dict[str, str]:
        """Contract output topic -> the name used here (``/diagnostics`` is fixed by ROS convention)."""
        return {
            MEAN_TOPIC: self.topic_mean,
            COVARIANCE_TOPIC: self.topic_covariance,
            **{COMPENSATED_TOPICS[ch]: getattr(self, f"topic_compensated_{ch}") for ch in CHANNELS},
            DIAGNOSTICS_TOPIC: DIAGNOSTICS_TOPIC,
        }

    @classmethod
    def from_params(cls, params: dict[str, Any], *, strict: bool = True) -> ShadowConfig:
        """Build from a flat ``{name: value}`` map; unknown names raise ConfigError when strict.

        Types are strict (see ``parameters.specs``): ``true`` is not 1.0, 2.7 is not 2.
        """
        names = [f.name for f in dataclasses.fields(cls)]
        if strict:
            check_keys(params, names, "shadow parameters", listing="see config/shadow.yaml")
        return cls(**{key: value for key, value in params.items() if key in names})

    def to_params(self) -> dict[str, Any]:
        """Flat ``{name: value}`` map (the ``ros__parameters`` section)."""
        return dataclasses.asdict(self)

    def replace(self, **changes: Any) -> ShadowConfig:
        """Return a copy with some parameters changed (validated)."""
        return dataclasses.replace(self, **changes)


def read_params_file(file: Path) -> dict[str, Any]:
    """Return the ``bridge_shadow: ros__parameters:`` map of a parameter file; ConfigError in one line."""
    if file.is_dir():
        raise ConfigError(f"{file}: is a directory, not a parameter file")
    if not file.is_file():
        raise ConfigError(f"{file}: parameter file not found")
    try:
        text = file.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as err:
        raise ConfigError(f"{file}: cannot read the parameter file ({err})") from None
    try:
        data = yaml.load(text, Loader=_Loader) or {}
    except yaml.YAMLError as err:
        raise ConfigError(f"{file}: not valid YAML at {yaml_problem(err)}") from None
    if not isinstance(data, dict):
        raise ConfigError(f"{file}: expected a mapping at the top level")
    section = data.get(NODE_NAME, data.get(f"/{NODE_NAME}", data.get("/**", {})))
    if not isinstance(section, dict) or "ros__parameters" not in section:
        raise ConfigError(f"{file}: expected '{NODE_NAME}: ros__parameters:' at the top level")
    params = section["ros__parameters"] or {}
    if not isinstance(params, dict):
        raise ConfigError(f"{file}: 'ros__parameters' must be a mapping of name: value")
    return dict(params)


def load_config(path: str | Path | None = None, overrides: dict[str, Any] | None = None) -> ShadowConfig:
    """Load ``config/shadow.yaml`` (or ``path``) and apply ``overrides``; ConfigError on problems."""
    file = Path(path) if path is not None else config_file("shadow.yaml")
    params: dict[str, Any] = {}
    if path is not None or file.is_file():
        params = read_params_file(file)
    params.update(overrides or {})
    try:
        return ShadowConfig.from_params(params)
    except ConfigError as err:
        raise ConfigError(f"{file}: {err}") from err

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
from bridge_shadow.estimate.prior import PRIOR_RULES
from bridge_shadow.paths import config_file

__all__ = ["ShadowConfig", "load_config"]

_MATCH_MODES = ("hold", "linear")
_SMOOTHING_MODES = ("reml", "gcv", "fixed", "none")
_NOISE_MODES = ("adaptive", "fixed")
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
    # temperature compensation (fitted jointly with the settlement levels)
    smoothing: str = "reml"
    spline_lambda: float = 10.0
    spline_t_min_c: float = -20.0
    spline_t_max_c: float = 45.0
    spline_segments: int = 13
    thermal_prior_sd_n_per_k: float = 500.0
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
    # gating
    force_min_n: float = 1.0
    force_max_n: float = 5.0e6
    temp_min_c: float = -60.0
    temp_max_c: float = 70.0
    mahalanobis_probability: float = 0.999999
    clock_jump_s: float = 3600.0
    clock_jump_confirm: int = 100
    check_frame_id: bool = True
    temperature_frame_id: str = TEMPERATURE_FRAME
    # checkpoint
    checkpoint_path: str = ""
    checkpoint_period_s: float = 600.0
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
        """Raise ConfigError on an inconsistent parameter set."""

        def need(cond: bool, msg: str) -> None:
            if not cond:
                raise ConfigError(f"shadow parameters: {msg}")

        need(self.window_s > 0, "window_s must be > 0")
        need(self.window_min_samples >= 1, "window_min_samples must be >= 1")
        need(self.temperature_match in _MATCH_MODES, f"temperature_match must be one of {_MATCH_MODES}")
        need(self.smoothing in _SMOOTHING_MODES, f"smoothing must be one of {_SMOOTHING_MODES}")
        need(self.noise_mode in _NOISE_MODES, f"noise_mode must be one of {_NOISE_MODES}")
        need(self.prior_rule in PRIOR_RULES, f"prior_rule must be one of {PRIOR_RULES}")
        need(self.spline_t_max_c > self.spline_t_min_c, "spline_t_max_c must exceed spline_t_min_c")
        need(self.spline_segments >= 1, "spline_segments must be >= 1")
        need(self.spline_lambda >= 0, "spline_lambda must be >= 0")
        need(self.thermal_prior_sd_n_per_k > 0, "thermal_prior_sd_n_per_k must be > 0")
        need(self.warmup_windows >= 1, "warmup_windows must be >= 1")
        need(self.refit_windows >= 1, "refit_windows must be >= 1")
        need(self.lambda_reselect_growth > 1.0, "lambda_reselect_growth must be > 1")
        need(self.drift_block_s >= self.window_s, "drift_block_s must be at least window_s")
        for name in ("prior_sigma_m", "process_noise_m2_per_s", "noise_sigma_n", "systematic_sigma_n"):
            value = getattr(self, name)
            need(len(value) == 2, f"{name} must have two values [south, north]")
            setattr(self, name, [float(v) for v in value])
        need(
            min(self.prior_sigma_m) > 0 or max(self.prior_sigma_m) == 0,
            "prior_sigma_m must be > 0, or [0, 0] for the paper's rule (prior_rule)",
        )
        need(min(self.noise_sigma_n) > 0, "noise_sigma_n must be > 0")
        need(min(self.process_noise_m2_per_s) >= 0, "process_noise_m2_per_s must be >= 0")
        need(min(self.systematic_sigma_n) >= 0, "systematic_sigma_n must be >= 0")
        need(0.0 <= self.noise_phi_max < 1.0, "noise_phi_max must be in [0, 1)")
        need(0.0 < self.mahalanobis_probability <= 1.0, "mahalanobis_probability must be in (0, 1]")
        need(0.0 < self.event_trigger_probability < 1.0, "event_trigger_probability must be in (0, 1)")
        need(0.0 < self.event_probability < 1.0, "event_probability must be in (0, 1)")
        need(self.event_confirm_windows >= 1, "event_confirm_windows must be >= 1")
        need(
            self.event_jump_rule in (*PRIOR_RULES, "prior"),
            f"event_jump_rule must be one of {(*PRIOR_RULES, 'prior')}",
        )
        need(
            self.event_max_pending > self.event_confirm_windows,
            "event_max_pending must exceed event_confirm_windows",
        )
        need(self.force_max_n > self.force_min_n, "force_max_n must exceed force_min_n")
        need(self.clock_jump_s > 0, "clock_jump_s must be > 0")
        need(self.clock_jump_confirm >= 1, "clock_jump_confirm must be >= 1")
        need(self.temperature_stale_s > 0 and self.topic_timeout_s >= 0, "timeouts must be positive")
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
        """Build from a flat ``{name: value}`` map; unknown names raise ConfigError when strict."""
        names = {f.name: f for f in dataclasses.fields(cls)}
        unknown = sorted(set(params) - set(names))
        if unknown and strict:
            raise ConfigError(f"shadow parameters: unknown name(s) {unknown}")
        kwargs: dict[str, Any] = {}
        for key, value in params.items():
            if key not in names:
                continue
            default = names[key].default
            try:
                if isinstance(default, bool):
                    if not isinstance(value, bool):
                        raise TypeError("expected true or false")
                    kwargs[key] = value
                elif isinstance(default, int):
                    kwargs[key] = int(value)
                elif isinstance(default, float):
                    kwargs[key] = float(value)
                elif isinstance(default, str):
                    kwargs[key] = str(value)
                else:
                    kwargs[key] = [float(v) for v in value]
            except (TypeError, ValueError) as err:
                raise ConfigError(f"shadow parameters: {key}: bad value {value!r} ({err})") from err
        return cls(**kwargs)

    def to_params(self) -> dict[str, Any]:
        """Flat ``{name: value}`` map (the ``ros__parameters`` section)."""
        return dataclasses.asdict(self)

    def replace(self, **changes: Any) -> ShadowConfig:
        """Return a copy with some parameters changed (validated)."""
        return dataclasses.replace(self, **changes)


def load_config(path: str | Path | None = None, overrides: dict[str, Any] | None = None) -> ShadowConfig:
    """Load ``config/shadow.yaml`` (or ``path``) and apply ``overrides``; ConfigError on problems."""
    file = Path(path) if path is not None else config_file("shadow.yaml")
    params: dict[str, Any] = {}
    if file.is_file():
        try:
            data = yaml.safe_load(file.read_text()) or {}
        except yaml.YAMLError as err:
            raise ConfigError(f"{file}: not valid YAML ({err})") from err
        if not isinstance(data, dict):
            raise ConfigError(f"{file}: expected a mapping at the top level")
        section = data.get(NODE_NAME, data.get(f"/{NODE_NAME}", data.get("/**", {})))
        if not isinstance(section, dict) or "ros__parameters" not in section:
            raise ConfigError(f"{file}: expected '{NODE_NAME}: ros__parameters:' at the top level")
        params = dict(section["ros__parameters"] or {})
    elif path is not None:
        raise ConfigError(f"{file}: parameter file not found")
    params.update(overrides or {})
    try:
        return ShadowConfig.from_params(params)
    except ConfigError as err:
        raise ConfigError(f"{file}: {err}") from err

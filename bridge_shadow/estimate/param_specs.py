"""The one table of the shadow's parameters: type, unit, range or choices, and what each shapes.

``ShadowConfig`` (``estimate/config.py``) holds the values and their defaults; this table adds,
per field, what a user needs to set it right and what the code needs to refuse it:

- the **type** comes from the dataclass field (bool, int, float, str, or two floats [south,
  north]) and is strict: ``true`` is not 1.0, 2.7 is not 2, ``window_s: true`` is an error; an
  integer is accepted for a real (``window_s: 60``), as YAML and ROS parameter files write it;
- the **unit** (SI, as in ``config/shadow.yaml``) and the **range** (open or closed ends) or the
  **choices**; a real must be finite (``.inf`` and NaN are refused) unless its spec allows it;
- ``shapes_state``: a checkpoint saved under another value cannot be resumed (its arrays mean
  something else), see ``estimate.checkpoint.check_compatible``;
- ``live``: the node applies a new value while it runs; every other parameter is read-only in
  the node once it has started (restart it with the new value).

The offline replay (``load_config``), ``ShadowConfig(...)`` from Python, the node's start-up
parameters, its ParameterDescriptors and its set-parameters callback all use ``check_value`` and
``constraint_text`` from here, so a parameter added to ``ShadowConfig`` gets all of them by adding
one entry to ``SPECS`` (a test checks that every field has one, and that its unit matches the
comment in ``config/shadow.yaml``). The descriptions are the comments of ``config/shadow.yaml``.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import re
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

from bridge_shadow.errors import ConfigError

__all__ = [
    "KINDS",
    "SPECS",
    "ParamSpec",
    "check_value",
    "constraint_text",
    "describe",
    "kind_of",
    "parameter_docs",
    "yaml_unit",
]

#: Value kinds of a parameter (from the ShadowConfig field's default).
KINDS = ("bool", "int", "float", "str", "float_pair")


@dataclass(frozen=True)
class ParamSpec:
    """Unit, range and role of one parameter.

    Attributes:
        unit: SI unit as written in ``config/shadow.yaml`` (``-`` for a count or a ratio, ``""``
            for text and switches).
        low, high: range ends (None: open-ended); ``low_open``/``high_open`` exclude the end.
        choices: allowed strings (empty: any string the field's own check accepts).
        finite: a real must be finite (every real here is).
        shapes_state: a checkpoint saved under another value cannot be resumed.
        live: the node applies a new value at run time (others are read-only once started).

    """

    unit: str = ""
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    choices: tuple[str, ...] = ()
    finite: bool = True
    shapes_state: bool = False
    live: bool = False


def _gt0(unit: str, **kw: Any) -> ParamSpec:
    return ParamSpec(unit, low=0.0, low_open=True, **kw)


def _ge(low: float, unit: str = "-", **kw: Any) -> ParamSpec:
    return ParamSpec(unit, low=low, **kw)


_TOPIC = ParamSpec()

#: Every parameter of ``ShadowConfig``: name -> spec (see the module docstring).
SPECS: dict[str, ParamSpec] = {
    # alignment and aggregation
    "window_s": _gt0("s", shapes_state=True),
    "window_min_samples": _ge(1),
    "temperature_match": ParamSpec(choices=("hold", "linear")),
    "temperature_stale_s": _gt0("s"),
    "topic_timeout_s": _ge(0.0, "s"),
    # temperature compensation (fitted jointly with the settlement levels)
    "smoothing": ParamSpec(choices=("reml", "gcv", "fixed", "none")),
    "spline_lambda": _ge(0.0, "N^2 per (N/C^2)^2 C"),
    "spline_t_min_c": ParamSpec("C", shapes_state=True),
    "spline_t_max_c": ParamSpec("C", shapes_state=True),
    "spline_segments": _ge(1, shapes_state=True),
    "thermal_prior_sd_n_per_k": _gt0("N/K"),
    "warmup_windows": _ge(1),
    "refit_windows": _ge(1),
    "lambda_reselect_growth": ParamSpec("-", low=1.0, low_open=True),
    # settlement prior and process noise
    "prior_sigma_m": _ge(0.0, "m", shapes_state=True),
    "prior_rule": ParamSpec(choices=("one_bearing", "both"), shapes_state=True),
    "process_noise_m2_per_s": _ge(0.0, "m^2/s"),
    "drift_block_s": _gt0("s", shapes_state=True),
    # measurement noise
    "noise_sigma_n": _gt0("N"),
    "systematic_sigma_n": _ge(0.0, "N"),
    "noise_mode": ParamSpec(choices=("adaptive", "fixed")),
    "noise_phi_max": ParamSpec("-", low=0.0, high=1.0, high_open=True),
    "noise_floor": ParamSpec(),
    # settlement events (GLR step detector)
    "event_detection": ParamSpec(),
    "event_trigger_probability": ParamSpec("-", low=0.0, high=1.0, low_open=True, high_open=True),
    "event_probability": ParamSpec("-", low=0.0, high=1.0, low_open=True, high_open=True),
    "event_confirm_windows": _ge(1),
    "event_max_pending": _ge(2),
    "gap_s": _gt0("s"),
    "change_prior_probability": ParamSpec("-", low=0.0, high=1.0, low_open=True, high_open=True),
    "change_confirm_probability": ParamSpec("-", low=0.5, high=1.0, low_open=True, high_open=True),
    "event_jump_rule": ParamSpec(choices=("one_bearing", "both", "prior")),
    # gating
    "force_min_n": ParamSpec("N"),
    "force_max_n": ParamSpec("N"),
    "temp_min_c": ParamSpec("C"),
    "temp_max_c": ParamSpec("C"),
    "mahalanobis_probability": ParamSpec("-", low=0.0, high=1.0, low_open=True),
    "clock_jump_s": _gt0("s"),
    "clock_jump_confirm": _ge(1),
    "check_frame_id": ParamSpec(),
    "temperature_frame_id": ParamSpec(),
    # checkpoint
    "checkpoint_path": ParamSpec(),
    "checkpoint_period_s": _gt0("s"),
    "checkpoint_unusable": ParamSpec(choices=("stop", "fresh")),
    # model
    "surrogate_path": ParamSpec(),
    # node only
    "qos_depth": _ge(0),
    # faster than 100 Hz is no use to a reader and only burns a core
    "diagnostics_period_s": _ge(0.01, "s", live=True),
    # topics (their names are checked by ShadowConfig.validate)
    "topic_frc_01": _TOPIC,
    "topic_frc_02": _TOPIC,
    "topic_air_temperature": _TOPIC,
    "topic_mean": _TOPIC,
    "topic_covariance": _TOPIC,
    "topic_compensated_frc_01": _TOPIC,
    "topic_compensated_frc_02": _TOPIC,
}
_DEFAULT_SPEC = ParamSpec()


def kind_of(field: dataclasses.Field) -> str:
    """Value kind of a ShadowConfig field, from its default: one of ``KINDS``."""
    default = field.default
    if default is dataclasses.MISSING and field.default_factory is not dataclasses.MISSING:
        default = field.default_factory()
    if isinstance(default, bool):
        return "bool"
    if isinstance(default, int):
        return "int"
    if isinstance(default, float):
        return "float"
    if isinstance(default, str):
        return "str"
    return "float_pair"


def _num(x: float) -> str:
    return f"{x:g}"


def constraint_text(name: str, kind: str) -> str:
    """Return the constraint of a parameter in words, e.g. ``a finite number > 0``, ``one of a, b``."""
    spec = SPECS.get(name, _DEFAULT_SPEC)
    if kind == "bool":
        return "true or false"
    if kind == "str":
        return "one of " + ", ".join(spec.choices) if spec.choices else "a string"
    what = "an integer" if kind == "int" else ("a finite number" if spec.finite else "a number")
    if kind == "float_pair":
        what = "two finite numbers [south, north]" if spec.finite else "two numbers [south, north]"
    lo, hi = spec.low, spec.high
    if lo is not None and hi is not None:
        left, right = "(" if spec.low_open else "[", ")" if spec.high_open else "]"
        rng = f" in {left}{_num(lo)}, {_num(hi)}{right}"
    elif lo is not None:
        rng = f" {'>' if spec.low_open else '>='} {_num(lo)}"
    elif hi is not None:
        rng = f" {'<' if spec.high_open else '<='} {_num(hi)}"
    else:
        rng = ""
    if kind == "float_pair" and rng:
        rng = ", each" + rng
    return what + rng


def _is_int(value: Any) -> bool:
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def _is_real(value: Any) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def _in_range(x: float, spec: ParamSpec) -> bool:
    if spec.low is not None and (x < spec.low or (spec.low_open and x == spec.low)):
        return False
    return not (spec.high is not None and (x > spec.high or (spec.high_open and x == spec.high)))


def check_value(name: str, value: Any, kind: str) -> Any:
    """Return ``value`` in its field's type (an integer widened to a real), or raise ConfigError.

    The message names the parameter, what it must be and what it got, e.g.
    ``window_s must be a finite number > 0, not true``.
    """
    spec = SPECS.get(name, _DEFAULT_SPEC)

    def refuse() -> ConfigError:
        shown = "true" if value is True else "false" if value is False else repr(value)
        return ConfigError(f"{name} must be {constraint_text(name, kind)}, not {shown}")

    if kind == "bool":
        if not isinstance(value, bool):
            raise refuse()
        return value
    if kind == "str":
        if not isinstance(value, str) or (spec.choices and value not in spec.choices):
            raise refuse()
        return value
    if kind == "int":
        if not _is_int(value) or not _in_range(float(value), spec):
            raise refuse()
        return int(value)
    if kind == "float":
        if not _is_real(value):
            raise refuse()
        x = float(value)
        if (spec.finite and not math.isfinite(x)) or math.isnan(x) or not _in_range(x, spec):
            raise refuse()
        return x
    # float_pair: [south, north]
    if isinstance(value, (str, bytes)) or not hasattr(value, "__len__") or len(value) != 2:
        raise refuse()
    out = []
    for v in value:
        if not _is_real(v):
            raise refuse()
        x = float(v)
        if (spec.finite and not math.isfinite(x)) or math.isnan(x) or not _in_range(x, spec):
            raise refuse()
        out.append(x)
    return out


_ENTRY = re.compile(r"^\s+([A-Za-z_][A-Za-z0-9_]*):")
_UNIT = re.compile(r"\[([^\[\]]+)\]\s*\(")


@lru_cache(maxsize=4)
def _docs(path: str) -> dict[str, str]:
    docs: dict[str, str] = {}
    block: list[str] = []
    previous = ""
    try:
        lines = Path(path).read_text(encoding="utf-8").splitlines()
    except OSError:
        return docs
    for line in lines:
        stripped = line.strip()
        if stripped.startswith("#"):
            text = stripped.lstrip("#").strip()
            if text.startswith("---"):
                block = []
            elif text:
                block.append(text)
            continue
        m = _ENTRY.match(line)
        if m and m.group(1) != "ros__parameters":
            doc = " ".join(block) or previous  # a pair (min, max) shares one comment
            docs[m.group(1)] = doc
            previous = doc
        block = []
    return docs


def parameter_docs(path: str | Path | None = None) -> dict[str, str]:
    """Comment text of each entry of ``config/shadow.yaml`` (or ``path``): name -> description."""
    if path is None:
        from bridge_shadow.paths import config_file

        path = config_file("shadow.yaml")
    return dict(_docs(str(path)))


def yaml_unit(doc: str) -> str | None:
    """Return the unit in brackets before the default, ``... [s] (60.0)`` -> ``s`` (None if none)."""
    m = _UNIT.search(doc)
    return m.group(1) if m else None


def describe(name: str, kind: str) -> str:
    """One description for people: the YAML comment, the unit, the constraint and the role."""
    spec = SPECS.get(name, _DEFAULT_SPEC)
    doc = parameter_docs().get(name, "see config/shadow.yaml")
    role = (
        " Changes apply while the node runs."
        if spec.live
        else " Read-only while the node runs (restart it with the new value)."
    )
    if spec.shapes_state:
        role += " A checkpoint saved under another value is not resumed."
    return f"{doc} Must be {constraint_text(name, kind)}.{role}"

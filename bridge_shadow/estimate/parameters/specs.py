"""The one table of the shadow's parameters: type, unit, range or choices, and what each shapes.

``ShadowConfig`` (``estimate/parameters/config.py``) holds the values and their defaults; this table adds,
per field, what a user needs to set it right and what the code needs to refuse it:

- the **type** comes from the dataclass field (bool, int, float, str, or two floats [south,
  north]) and is strict: ``true`` is not 1.0, 2.7 is not 2, ``window_s: true`` is an error; an
  integer is accepted for a real (``window_s: 60``), as YAML and ROS parameter files write it;
- the **unit** (SI, as in ``config/shadow.yaml``) and the **range** (open or closed ends) or the
  **choices**; a real must be finite (``.inf`` and NaN are refused) unless its spec allows it;
- ``shapes_state``: a checkpoint saved under another value cannot be resumed (its arrays mean
  something else), see ``estimate.state.checkpoint.check_compatible``;
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
    "VALUE_SPECS",
    "ParamSpec",
    "check_settlement_m",
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


def _gt0(unit: str, high: float, **kw: Any) -> ParamSpec:
    return ParamSpec(unit, low=0.0, low_open=True, high=high, **kw)


def _ge(low: float, high: float, unit: str = "-", **kw: Any) -> ParamSpec:
    return ParamSpec(unit, low=low, high=high, **kw)


_TOPIC = ParamSpec()

# The physical ends every range below is built from (each a value a real bridge, sensor or run
# can take, with the reason); a parameter beyond them is a typo or a unit mistake (1e12 s for 60 s,
# metres for millimetres), never a choice, and is refused by name before it can overflow a
# variance or blame another parameter's cross-check.
#: A day [s]: the longest window, timeout or period that still follows a daily temperature cycle
#: (the compensation needs several windows per day; a window of a day averages the cycle away).
DAY_S = 86_400.0
#: A year [s]: the longest clock jump or drift block a monitoring record can hold.
YEAR_S = 365.25 * DAY_S
#: A metre [m]: the largest settlement a supported bridge can take (it lifts off its bearings at
#: 20 mm with the calibrated model, 4.5 mm as built: README, Prior); a prior wider than that says
#: nothing, and a variance of (1e150 m)^2 overflows the filter.
METRE_M = 1.0
#: Load-cell forces [N]: ten 1000 t load cells' capacity (1e7 N), forty times the central reaction
#: of about 240 kN: a larger gate limit, noise or systematic error is not a reaction of this bridge.
FORCE_LIMIT_N = 1.0e7
#: Air temperature [C]: the records on earth are -89.2 C and +56.7 C; a gate or knot range beyond
#: a hundred kelvin either side of freezing is not weather.
TEMP_LIMIT_C = 100.0
#: Windows [-]: a year of the shortest useful windows (1 s): the largest count of windows to wait
#: for, hold or refit after.
WINDOWS_MAX = 31_557_600
#: Samples in a window [-]: a day at the 1 kHz acquisition rate on both channels.
SAMPLES_MAX = 86_400_000
#: Random-walk intensity [m^2/s]: a metre a day (sqrt(q * 1 day) = 1 m), far beyond any scour.
Q_MAX_M2_PER_S = METRE_M**2 / DAY_S

#: Every parameter of ``ShadowConfig``: name -> spec (see the module docstring).
SPECS: dict[str, ParamSpec] = {
    # alignment and aggregation
    "window_s": _gt0("s", DAY_S, shapes_state=True),
    "window_min_samples": _ge(1, SAMPLES_MAX),
    "temperature_match": ParamSpec(choices=("hold", "linear")),
    "temperature_stale_s": _gt0("s", DAY_S),
    "topic_timeout_s": _ge(0.0, DAY_S, "s"),
    # the screen holds a record in memory until it ends: a day at most (0 switches it off)
    "traffic_hold_s": _ge(0.0, DAY_S, "s"),
    # a vehicle adds at least the 1 s noise (~20 N); more than the whole dead load is not a vehicle
    "traffic_threshold_n": _gt0("N", 1.0e6),
    "traffic_margin_s": _ge(0.0, 600.0, "s"),
    # a rise of the car-free level above this is no vehicle (at least the screen's threshold)
    "traffic_vehicle_max_n": _gt0("N", 1.0e7),
    # temperature compensation (fitted jointly with the settlement levels)
    "smoothing": ParamSpec(choices=("reml", "gcv", "fixed", "none")),
    # lambda is in C^3 (the penalty integrates g''^2 over C). At 1e12 the fitted curve is a straight
    # line to 3e-11 of its range (at 1e9 to 3e-8; test_parameters): a larger one changes nothing
    "spline_lambda": _ge(0.0, 1.0e12, "N^2 per (N/C^2)^2 C"),
    "spline_t_min_c": _ge(-TEMP_LIMIT_C, TEMP_LIMIT_C, "C", shapes_state=True),
    "spline_t_max_c": _ge(-TEMP_LIMIT_C, TEMP_LIMIT_C, "C", shapes_state=True),
    # 2000 knot intervals over the widest range (200 K) are 0.1 K apart: an air sensor's accuracy
    "spline_segments": _ge(1, 2000, shapes_state=True),
    # the uniform-temperature response is +9 to +21 N/K (README, The model); a prior sd of the whole
    # central reaction per kelvin is no prior
    "thermal_prior_sd_n_per_k": _gt0("N/K", FORCE_LIMIT_N),
    # the sun term adds a basis column; EN 1991-1-5 Table 6.1 gives at most 15-18 K for any deck
    # type (heating, cooling): +-30 K is beyond every deck and every weather (the default sd is
    # half the top of effects.py's vertical_gradient range; test_sun_term)
    "sun_gradient": ParamSpec(shapes_state=True),
    "sun_gradient_prior_mean_k": _ge(-30.0, 30.0, "K"),
    "sun_gradient_prior_sd_k": _gt0("K", 30.0),
    # a Bayes factor (0: the term always in); 1e6 is beyond any day's evidence of a few kelvin
    "sun_gradient_min_bayes_factor": _ge(0.0, 1.0e6, "-"),
    "sun_gradient_fit": ParamSpec(choices=("average", "deck", "per_bearing")),
    # EN 1992-1-1 Annex B: phi_0 is 0.5-4 for any concrete, age and climate (0 switches it off)
    "relaxation_phi0": _ge(0.0, 5.0, "-"),
    "relaxation_horizon_s": _ge(0.0, DAY_S, "s"),
    "warmup_windows": _ge(1, WINDOWS_MAX),
    "refit_windows": _ge(1, WINDOWS_MAX),
    # a factor of growth: 1000 is never reached by a year of windows after a few hundred of them
    "lambda_reselect_growth": ParamSpec("-", low=1.0, low_open=True, high=1000.0),
    # settlement prior and process noise
    "prior_sigma_m": _ge(0.0, METRE_M, "m", shapes_state=True),
    "prior_rule": ParamSpec(choices=("one_bearing", "both"), shapes_state=True),
    "process_noise_m2_per_s": _ge(0.0, Q_MAX_M2_PER_S, "m^2/s"),
    "drift_block_s": _gt0("s", YEAR_S, shapes_state=True),
    # measurement noise
    "noise_sigma_n": _gt0("N", FORCE_LIMIT_N),
    "systematic_sigma_n": _ge(0.0, FORCE_LIMIT_N, "N"),
    "noise_mode": ParamSpec(choices=("adaptive", "fixed")),
    "noise_phi_max": ParamSpec("-", low=0.0, high=1.0, high_open=True),
    "noise_floor": ParamSpec(),
    # settlement events (GLR step detector)
    "event_detection": ParamSpec(),
    "event_trigger_probability": ParamSpec("-", low=0.0, high=1.0, low_open=True, high_open=True),
    "event_probability": ParamSpec("-", low=0.0, high=1.0, low_open=True, high_open=True),
    "event_confirm_windows": _ge(1, WINDOWS_MAX),
    "event_max_pending": _ge(2, WINDOWS_MAX),
    # a gap of a year still leaves the supports a chance to have moved (campaigns, long outages)
    "gap_s": _gt0("s", YEAR_S),
    "change_prior_probability": ParamSpec("-", low=0.0, high=1.0, low_open=True, high_open=True),
    "change_confirm_probability": ParamSpec("-", low=0.5, high=1.0, low_open=True, high_open=True),
    "event_jump_rule": ParamSpec(choices=("one_bearing", "both", "prior")),
    # gating
    "force_min_n": _ge(-FORCE_LIMIT_N, FORCE_LIMIT_N, "N"),
    "force_max_n": _ge(-FORCE_LIMIT_N, FORCE_LIMIT_N, "N"),
    "temp_min_c": _ge(-TEMP_LIMIT_C, TEMP_LIMIT_C, "C"),
    "temp_max_c": _ge(-TEMP_LIMIT_C, TEMP_LIMIT_C, "C"),
    "mahalanobis_probability": ParamSpec("-", low=0.0, high=1.0, low_open=True),
    "clock_jump_s": _gt0("s", YEAR_S),
    "clock_jump_confirm": _ge(1, WINDOWS_MAX),
    "check_frame_id": ParamSpec(),
    "temperature_frame_id": ParamSpec(),
    # checkpoint
    "checkpoint_path": ParamSpec(),
    "checkpoint_period_s": _gt0("s", YEAR_S),
    "checkpoint_unusable": ParamSpec(choices=("stop", "fresh")),
    # model
    "surrogate_path": ParamSpec(),
    # node only: a reader's history beyond a day of 1 kHz samples is memory, not reliability
    "qos_depth": _ge(0, SAMPLES_MAX),
    # faster than 100 Hz is no use to a reader and only burns a core; slower than a day is silence
    "diagnostics_period_s": _ge(0.01, DAY_S, "s", live=True),
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

#: Values that are not shadow parameters, checked by the same ``check_value`` with these specs:
#: command-line options (``replay --rate``, ``synth --days``, ``gap --window``, ``--imposed``,
#: ``synth --step``) and the calibration file's numbers (``calibrate.spec``). Name -> spec.
VALUE_SPECS: dict[str, ParamSpec] = {
    # a settlement step, imposed or simulated (m, positive upward): less than a metre either way
    "settlement_m": ParamSpec("m", low=-METRE_M, high=METRE_M, low_open=True, high_open=True),
    # the jacks' accuracy (1 sd): more than 10 cm is no known settlement
    "imposed_sd_m": ParamSpec("m", low=0.0, high=0.1, low_open=True),
    # a central reaction of a reference record (compression positive): 0 is a lifted bearing
    "reactions_n": ParamSpec("N", low=0.0, high=FORCE_LIMIT_N, low_open=True),
    # the calibration's car-free windows: at least 10 samples of the 100 Hz records, and at most
    # ten minutes, beyond which a 12-minute record with the test car on it has no car-free window
    "calibration_window_s": ParamSpec("s", low=0.1, high=600.0),
    # replay --live --rate: a speed factor of log time; 1e7 plays a year in 3 s, faster than any
    # node takes it (the player then publishes as fast as it is taken anyway); 1e-3 plays a
    # minute's window in 17 hours, slower than anyone watches (1e-9 made a wait the OS refuses)
    "rate": ParamSpec("-", low=1.0e-3, high=1.0e7),
    # synth: a record of at most a year (the twin holds it in memory), forces and air
    # temperature at most at the 1 kHz acquisition rate
    "days": ParamSpec("day", low=0.0, high=366.0, low_open=True),
    "rate_hz": ParamSpec("Hz", low=0.0, high=1000.0, low_open=True),
}


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
    """Write a range end for people: whole numbers in full (86400, 31557600), others as ``%g``."""
    return str(int(x)) if float(x).is_integer() and abs(x) < 1e12 else f"{x:g}"


def constraint_text(name: str, kind: str, spec: ParamSpec | None = None) -> str:
    """Return the constraint of a parameter in words, e.g. ``a finite number > 0``, ``one of a, b``.

    ``spec`` is the parameter's own (default: its entry in ``SPECS``; ``VALUE_SPECS`` for values
    that are not shadow parameters).
    """
    spec = spec if spec is not None else SPECS.get(name, _DEFAULT_SPEC)
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


def check_settlement_m(name: str, value: float) -> float:
    """Check a settlement given in metres (``VALUE_SPECS["settlement_m"]``); ConfigError if not.

    A value of a metre or more is most likely millimetres: the message says the unit and what the
    number would be in metres.
    """
    try:
        return check_value(name, value, "float", VALUE_SPECS["settlement_m"])
    except ConfigError as err:
        if not 1.0 <= abs(value) < math.inf:
            raise
        raise ConfigError(f"{err} (metres, positive upward: {value:g} mm is {value / 1000:g})") from None


def check_value(name: str, value: Any, kind: str, spec: ParamSpec | None = None) -> Any:
    """Return ``value`` in its field's type (an integer widened to a real), or raise ConfigError.

    The message names the parameter, what it must be and what it got, e.g.
    ``window_s must be a finite number > 0, not true``. ``spec`` as in ``constraint_text``.
    """
    spec = spec if spec is not None else SPECS.get(name, _DEFAULT_SPEC)

    def refuse() -> ConfigError:
        shown = "true" if value is True else "false" if value is False else repr(value)
        return ConfigError(f"{name} must be {constraint_text(name, kind, spec)}, not {shown}")

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

"""The truth twin: a synthetic monitoring record of the bridge with known effects.

``simulate`` draws weather, sensors, data loss and (with the ``traffic`` effect) test-car crossings
from independent random streams of one seed, and maps them to the two central reactions::

    F(t) = u0' + A' x(t)                                  settlements (offset, drift, steps)
         + thermal'[uniform] (T_air - T_ref)              the baseline FE thermal response
         + c (T_struct - T_ref)                           uniform_temperature effect
         + thermal'[vertical_gradient] dT_v(t)            vertical_gradient, thermal_lag effects
         + thermal'[transverse_gradient] dT_t(t)          transverse_gradient effect
         + traffic(t)                                     traffic effect
         + noise(t) + [0, d t_days]                       sensors; sensor_drift effect (north)

with the primed surrogate changed by the model-form effects (``bearing_stiffness``,
``connector_stiffness``, ``slab_joint_opening`` first order; ``support_spring`` exact; traffic
through the same load map), ``T_ref`` the mean noise-free air
temperature over the record, ``T_struct`` the air temperature through the thermal lag (the air
itself without the ``thermal_lag`` effect), ``dT_v = g_v sun clearness + (T_air - T_struct)`` and
``dT_t = g_t sun clearness``. Every effect's meaning is the one in ``bridge_shadow.effects``. With
no effect, the record is the baseline model plus noise, dropouts and NaNs.

Each part draws from its own stream (``SeedSequence([seed, part])``), so switching an effect on
changes the forces by exactly that effect's term and nothing else.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from bridge_shadow.contract import CHANNELS, FORCE_FRAMES
from bridge_shadow.effects import EFFECT_NAMES, EFFECTS, format_support_springs, parse_support_springs
from bridge_shadow.errors import InputError
from bridge_shadow.model.surrogate_file import Surrogate
from bridge_shadow.series import ForceSeries, MonitoringData, TemperatureSeries
from bridge_shadow.sun import clear_sky
from bridge_shadow.twin.config import DEFAULT_START, TwinConfig
from bridge_shadow.twin.response import apply_stiffness, load_twin_surrogate, stiffness_sensitivities
from bridge_shadow.twin.sensors import dropout_mask, load_cell_noise, nan_positions
from bridge_shadow.twin.traffic import draw_crossings, traffic_reactions
from bridge_shadow.twin.weather import Weather

__all__ = ["DEFAULT_TEMP_RATE_HZ", "parse_effects", "simulate", "validate_effects"]

NS = 1_000_000_000
DAY_S = 86_400.0
#: Default air-temperature rate: one message a minute (the shadow aggregates to 60 s windows).
DEFAULT_TEMP_RATE_HZ = 1.0 / 60.0
#: Largest record the twin writes in one go (messages per force channel).
MAX_SAMPLES = 20_000_000
#: Random stream of each part of the world (independent of each other for one seed).
_STREAMS = {"weather": 1, "noise": 2, "force_gaps": 3, "force_nan": 4, "temp": 5, "traffic": 6}


def _rng(seed: int, part: str, segment: int = 0) -> np.random.Generator:
    """Return the random stream of one part of the world (``segment`` > 0: of a long record's segment)."""
    key = [int(seed), _STREAMS[part]] + ([int(segment)] if segment else [])
    return np.random.default_rng(np.random.SeedSequence(key))


def temperature_span(
    i0: int, i1: int, n: int, n_temp: int, rate_hz: float, temp_rate_hz: float
) -> tuple[int, int]:
    """Return the air-temperature samples ``[j0, j1)`` that fall in force samples ``[i0, i1)`` of a record.

    Sample ``j`` is at ``j / temp_rate_hz`` s and belongs to the span starting at or before it; the
    spans of consecutive force ranges tile ``[0, n_temp)``.
    """

    def first(i: int) -> int:
        return (
            0
            if i <= 0
            else n_temp
            if i >= n
            else min(int(np.ceil(i * temp_rate_hz / rate_hz - 1e-9)), n_temp)
        )

    return first(i0), first(i1)


def validate_effects(effects: Mapping[str, Any] | None) -> dict[str, Any]:
    """Check names and values against the vocabulary; return ``{name: value}`` in vocabulary order.

    Every value is a float, except ``support_spring`` whose one-bearing or two-value forms
    (``south:K``, ``north:K``, ``KS,KN``) stay a canonical string (``format_support_springs``).
    """
    effects = dict(effects or {})
    unknown = sorted(set(effects) - set(EFFECT_NAMES))
    if unknown:
        raise InputError(f"unknown effect {', '.join(unknown)}; valid effects: {', '.join(EFFECT_NAMES)}")
    out: dict[str, Any] = {}
    for name in EFFECT_NAMES:
        if name not in effects:
            continue
        if name == "support_spring":
            try:
                out[name] = format_support_springs(parse_support_springs(effects[name]))
            except ValueError as err:
                raise InputError(
                    f"effect support_spring: {err}; give K (N/m, both bearings), south:K, north:K or KS,KN"
                ) from None
            continue
        try:
            value = float(effects[name])
        except (TypeError, ValueError):
            raise InputError(f"effect {name}: value {effects[name]!r} is not a number") from None
        if not np.isfinite(value):
            raise InputError(f"effect {name}: value must be finite")
        if name == "thermal_lag" and value < 0.0:
            raise InputError("effect thermal_lag: the time constant (h) must not be negative")
        if name in ("bearing_stiffness", "connector_stiffness") and value <= -1.0:
            raise InputError(f"effect {name}: the relative change must be greater than -1")
        if name == "slab_joint_opening" and not 0.0 <= value <= 1.0:
            raise InputError("effect slab_joint_opening: the fraction of joint stiffness kept is in [0, 1]")
        out[name] = value
    return out


def parse_effects(items: Iterable[str]) -> dict[str, Any]:
    """Parse ``NAME=VALUE`` strings (the ``--effect`` arguments) into a validated dict."""
    raw: dict[str, str] = {}
    for item in items:
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep or not name:
            raise InputError(
                f"--effect {item!r}: expected NAME=VALUE; valid effects: {', '.join(EFFECT_NAMES)}"
            )
        if name in raw:
            raise InputError(f"--effect {name} given twice")
        raw[name] = value.strip()
    return validate_effects(raw)


def _start_ns(start: dt.datetime | str | int | None) -> int:
    if start is None:
        start = DEFAULT_START
    if isinstance(start, (int, np.integer)):
        return int(start)
    if isinstance(start, str):
        try:
            start = dt.datetime.fromisoformat(start)
        except ValueError:
            raise InputError(f"start {start!r} is not an ISO 8601 date/time") from None
    if start.tzinfo is None:
        start = start.replace(tzinfo=DEFAULT_START.tzinfo)
    delta = start - dt.datetime(1970, 1, 1, tzinfo=dt.timezone.utc)  # exact integer arithmetic
    return (delta.days * 86_400 + delta.seconds) * NS + delta.microseconds * 1000


def _settlement_path(
    t_day: np.ndarray,
    effects: dict[str, Any],
    steps: Sequence[tuple[float, float, float]],
    days: float,
) -> np.ndarray:
    """Return the true settlements x (n, 2) in m, positive upward [south, north]."""
    x = np.zeros((len(t_day), 2))
    v = effects.get("settlement_offset", 0.0)
    x += np.array([v, -v])
    x[:, 0] -= effects.get("settlement_drift", 0.0) * t_day
    if effects.get("settlement_step", 0.0) and len(t_day):
        x[t_day >= 0.5 * days] += effects["settlement_step"]
    for t_step, dx_south, dx_north in steps:
        x[t_day >= t_step] += np.array([dx_south, dx_north])
    return x


def _brief(surrogate: Surrogate) -> dict[str, Any]:
    """``surrogate.to_dict()`` with a calibration's provenance cut to its chosen explanation."""
    out = surrogate.to_dict()
    cal = out["provenance"].get("calibration")
    if isinstance(cal, dict):
        keep = ("chosen_explanation", "file_sha256", "bridge_model_sha256", "mesh")
        out["provenance"] = {**out["provenance"], "calibration": {k: cal.get(k) for k in keep}}
    return out


def _summary(x: np.ndarray) -> dict[str, list[float]]:
    if not len(x):
        return {"mean_m": [0.0, 0.0], "start_m": [0.0, 0.0], "end_m": [0.0, 0.0]}
    return {"mean_m": x.mean(axis=0).tolist(), "start_m": x[0].tolist(), "end_m": x[-1].tolist()}


def simulate(
    days: float = 3.0,
    rate_hz: float = 1.0,
    seed: int = 0,
    effects: Mapping[str, Any] | None = None,
    start: dt.datetime | str | int | None = None,
    *,
    temp_rate_hz: float = DEFAULT_TEMP_RATE_HZ,
    steps: Sequence[tuple[float, float, float]] = (),
    config: TwinConfig | None = None,
    surrogate: Surrogate | None = None,
    sensitivities_block: dict[str, Any] | None = None,
    reality: dict[str, Any] | None = None,
    span: tuple[int, int] | None = None,
    segment: int = 0,
) -> tuple[MonitoringData, dict[str, Any]]:
    """Simulate ``days`` of monitoring; return the data and the truth.

    Args:
        days: record length in days (> 0).
        rate_hz: force sample rate per channel, Hz (both channels share the stamps).
        seed: random seed; the same seed gives identical arrays.
        effects: ``{name: magnitude}`` from the vocabulary (``bridge_shadow.effects``), SI units.
        start: first stamp: aware datetime, naive datetime or ISO string in Europe/Berlin, or UTC
            ns; default 2022-03-14 00:00 Europe/Berlin.
        temp_rate_hz: air-temperature message rate, Hz (default one a minute).
        steps: extra settlement steps ``(t_day, dx_south_m, dx_north_m)`` from ``t_day`` on.
        config: the world's parameters (``TwinConfig()`` by default).
        surrogate: the structural map (the twin's reality); default ``config/surrogate.yaml`` or
            its placeholder. It may differ from the estimator's (``bridge_shadow.twin.reality``).
        sensitivities_block: stiffness sensitivities in the file format (with ``surrogate``).
        reality: where ``surrogate`` comes from (recorded as ``truth["reality"]``).
        span: simulate only the force samples ``[i0, i1)`` of the record (and the temperature
            samples between them, ``temperature_span``): one segment of a record too long to hold
            (``twin.stream``). Weather, test-car crossings, the reference temperature and the
            settlement path are the whole record's; the sensors draw from the segment's own
            streams (``segment`` > 0). Default: the whole record.
        segment: the segment's number (0: the streams of a whole record).

    Returns:
        ``(data, truth)``: ``truth`` holds every parameter, the effects, the seed, the surrogate
        used and a summary of the true settlement path (``settlement``: mean, start, end in m), and
        under ``series`` the noise-free arrays (not written to ``truth.yaml``).

    """
    cfg = config or TwinConfig()
    eff = validate_effects(effects)
    if not (np.isfinite(days) and days > 0.0):
        raise InputError(f"days must be positive (got {days})")
    if not (np.isfinite(rate_hz) and rate_hz > 0.0):
        raise InputError(f"rate must be positive (got {rate_hz} Hz)")
    if not (np.isfinite(temp_rate_hz) and temp_rate_hz > 0.0):
        raise InputError(f"temperature rate must be positive (got {temp_rate_hz} Hz)")
    n = int(np.floor(days * DAY_S * rate_hz + 1e-9))
    n_temp = int(np.floor(days * DAY_S * temp_rate_hz + 1e-9))
    i0, i1 = (0, n) if span is None else (max(int(span[0]), 0), min(int(span[1]), n))
    j0, j1 = temperature_span(i0, i1, n, n_temp, rate_hz, temp_rate_hz)
    if i1 - i0 > MAX_SAMPLES or j1 - j0 > MAX_SAMPLES:
        raise InputError(
            f"{days} days at {rate_hz} Hz is {n} samples per channel; the limit is {MAX_SAMPLES}"
        )
    if n < 1 or n_temp < 1:
        raise InputError("the record is shorter than one sample; raise --days or --rate")
    if i1 <= i0:
        raise InputError(f"span {span} holds no force sample of the record's {n}")
    steps = [tuple(float(v) for v in s) for s in steps]
    if surrogate is None:
        base, block = load_twin_surrogate()
    else:
        base, block = surrogate, sensitivities_block

    t0 = _start_ns(start)
    t_ns = t0 + np.round(np.arange(i0, i1) * (NS / rate_hz)).astype(np.int64)
    tt_ns = t0 + np.round(np.arange(j0, j1) * (NS / temp_rate_hz)).astype(np.int64)
    t1 = int(max(t0 + round((n - 1) * (NS / rate_hz)), t0 + round((n_temp - 1) * (NS / temp_rate_hz))))
    seg_days = days if span is None else (i1 - i0) / rate_hz / DAY_S
    n, n_temp = i1 - i0, j1 - j0  # from here on: this call's samples
    t_day = (t_ns - t0) / (DAY_S * NS)

    # Weather, sun and structure temperatures.
    weather = Weather.draw(int(t0 - cfg.spinup_days * DAY_S * NS), t1, _rng(seed, "weather"), cfg)
    t_air = weather.air_temp_c(t_ns)
    record_grid = weather.grid_ns[(weather.grid_ns >= t0) & (weather.grid_ns <= t1)]
    t_ref = float(weather.air_temp_c(record_grid).mean())
    tau_h = eff.get("thermal_lag", 0.0)
    t_struct = weather.lagged_temp_c(t_ns, tau_h)
    sun = clear_sky(t_ns)
    clearness = weather.clearness_at(t_ns)
    dtv = eff.get("vertical_gradient", 0.0) * sun * clearness + (t_air - t_struct)
    dtt = eff.get("transverse_gradient", 0.0) * sun * clearness

    # Structure: surrogate changed by the model-form effects (first order in r, support springs
    # exact; slab_joint_opening keeps the fraction f, r = f - 1).
    sens = stiffness_sensitivities(base, block)
    ratios = {k: float(eff.get(k, 0.0)) for k in ("bearing_stiffness", "connector_stiffness")}
    if "slab_joint_opening" in eff:
        ratios["slab_joint_opening"] = float(eff["slab_joint_opening"]) - 1.0
    springs = parse_support_springs(eff["support_spring"]) if "support_spring" in eff else (np.inf, np.inf)
    sur, load_map = apply_stiffness(base, sens, ratios, springs)
    zero = np.zeros(2)
    x = _settlement_path(t_day, eff, steps, days)
    parts = {
        "dead_load": np.broadcast_to(sur.u0, (n, 2)).copy(),
        "settlement": x @ sur.A.T,
        "thermal_uniform": np.outer(t_air - t_ref, sur.thermal.get("uniform", zero)),
        "uniform_temperature": np.outer(t_struct - t_ref, np.full(2, eff.get("uniform_temperature", 0.0))),
        "vertical_gradient": np.outer(dtv, sur.thermal.get("vertical_gradient", zero)),
        "transverse_gradient": np.outer(dtt, sur.thermal.get("transverse_gradient", zero)),
    }
    crossings = draw_crossings(_rng(seed, "traffic"), t0, t1, cfg)
    weight = eff.get("traffic", 0.0)
    parts["traffic"] = traffic_reactions(t_ns, crossings, weight, cfg.span_m) @ load_map.T
    clean = sum(parts.values())

    # Sensors.
    noise = load_cell_noise(_rng(seed, "noise", segment), 1.0 / rate_hz, n, cfg)
    drift = np.zeros((n, 2))
    drift[:, 1] = eff.get("sensor_drift", 0.0) * t_day
    measured = clean + drift + noise
    rng_nan = _rng(seed, "force_nan", segment)
    nan_idx = [nan_positions(rng_nan, n, cfg.nan_per_day, seg_days) for _ in CHANNELS]
    for i, idx in enumerate(nan_idx):
        measured[idx, i] = np.nan
    keep = dropout_mask(
        _rng(seed, "force_gaps", segment),
        t_ns,
        cfg.gaps_per_day,
        cfg.gap_median_s,
        2,
        cfg.gap_single_fraction,
    )
    forces = {
        ch: ForceSeries(t_ns[keep[:, i]], measured[keep[:, i], i], FORCE_FRAMES[ch])
        for i, ch in enumerate(CHANNELS)
    }

    rng_temp = _rng(seed, "temp", segment)
    temp = weather.air_temp_c(tt_ns) + cfg.temp_sensor_sd_k * rng_temp.standard_normal(n_temp)
    temp_nan = nan_positions(rng_temp, n_temp, cfg.temp_nan_per_day, seg_days)
    temp[temp_nan] = np.nan
    tkeep = dropout_mask(rng_temp, tt_ns, cfg.temp_gaps_per_day, cfg.gap_median_s)[:, 0]
    temperature = TemperatureSeries(
        tt_ns[tkeep], temp[tkeep], np.full(int(tkeep.sum()), cfg.temp_sensor_sd_k**2)
    )
    data = MonitoringData(forces, temperature)

    start_utc = dt.datetime.fromtimestamp(t0 / NS, dt.timezone.utc)
    truth: dict[str, Any] = {
        "generator": "bridge_shadow.twin.simulate",
        "seed": int(seed),
        "days": float(days),
        "rate_hz": float(rate_hz),
        "temp_rate_hz": float(temp_rate_hz),
        "start": start_utc.isoformat(),
        "start_local": start_utc.astimezone(DEFAULT_START.tzinfo).isoformat(),
        "start_ns": int(t0),
        "effects": dict(eff),
        "effect_units": {k: EFFECTS[k].unit for k in eff},
        "steps": [list(s) for s in steps],
        "config": cfg.to_dict(),
        "t_ref_c": t_ref,
        "reality": dict(reality) if reality else {"source": "default" if surrogate is None else "given"},
        "surrogate": _brief(sur),
        "base_surrogate": _brief(base),
        "sensitivities": {k: v.to_dict() for k, v in sens.items()},
        "traffic_load_map": load_map.tolist(),
        "settlement": _summary(x),
        "counts": {
            "force_samples": n,
            "force_messages": {ch: len(s) for ch, s in forces.items()},
            "force_nan": {ch: int(np.isnan(s.force_n).sum()) for ch, s in forces.items()},
            "force_dropped": {ch: int((~keep[:, i]).sum()) for i, ch in enumerate(CHANNELS)},
            "temperature_samples": n_temp,
            "temperature_messages": len(temperature),
            "temperature_nan": int(np.isnan(temperature.temp_c).sum()),
            "crossings": len(crossings) if weight else 0,
        },
        "weather": {
            "first_solar_day": weather.day0,
            "clearness": weather.clearness.tolist(),
            "level_c": weather.level_c.tolist(),
            "swing_k": weather.swing_k.tolist(),
        },
        "series": {
            "stamp_ns": t_ns,
            "x_m": x,
            "clean_force_n": clean,
            "parts_n": parts,
            "noise_n": noise,
            "drift_n": drift,
            "air_temp_c": t_air,
            "struct_temp_c": t_struct,
            "vertical_gradient_k": dtv,
            "transverse_gradient_k": dtt,
            "sun": sun,
            "clearness": clearness,
            "crossing_start_ns": crossings.start_ns if weight else np.zeros(0, np.int64),
        },
    }
    if span is not None:
        truth["segment"] = {"index": int(segment), "force_samples": [i0, i1], "temperature_samples": [j0, j1]}
    return data, truth

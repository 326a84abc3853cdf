"""Gap diagnosis core on numpy-made data: aggregation, drivers, fitting, ambiguity, noise level."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import lfilter

from bridge_shadow.gap.candidates import CANDIDATES, stiffness_sensitivities
from bridge_shadow.gap.diagnose import diagnose
from bridge_shadow.gap.drivers import lowpass
from bridge_shadow.gap.errors import GapError
from bridge_shadow.gap.fit import ar1_phi, cross_validate, folds_of
from bridge_shadow.gap.windows import aggregate
from bridge_shadow.model.surrogate_file import placeholder_surrogate
from bridge_shadow.series import ForceSeries, MonitoringData, TemperatureSeries
from bridge_shadow.sun import clear_sky

NS = 10**9
T0 = 1_649_635_200 * NS  # 2022-04-11 00:00 UTC


def _record(effect: dict[str, float], seed: int = 0, days: int = 3, phi: float = 0.9) -> MonitoringData:
    """One force sample per 60 s window: baseline + AR(1) noise (+ an effect), placeholder model."""
    s = placeholder_surrogate()
    rng = np.random.default_rng(seed)
    n = days * 1440
    t_ns = T0 + np.arange(n, dtype=np.int64) * 60 * NS + 30 * NS
    h = np.arange(n) / 60.0
    temp = 8.0 + 7.0 * np.sin(2 * np.pi * (h - 9.0) / 24.0) + 0.3 * h / 24
    y = np.tile(s.u0, (n, 1))
    t_day = h / 24.0
    if "settlement_offset" in effect:
        v = effect["settlement_offset"]
        y += s.A @ np.array([v, -v])
    if "settlement_drift" in effect:
        y += np.outer(-effect["settlement_drift"] * t_day, s.A[:, 0])
    if "sensor_drift" in effect:
        y[:, 1] += effect["sensor_drift"] * t_day
    sd = np.array([60.4, 82.7])
    noise = lfilter([1.0], [1.0, -phi], rng.standard_normal((n, 2)) * sd * np.sqrt(1 - phi**2), axis=0)
    return MonitoringData.from_arrays(t_ns, y + noise, t_ns, temp)


def test_aggregate_matches_loop_reference():
    rng = np.random.default_rng(3)
    t = np.sort(rng.integers(T0, T0 + 600 * NS, 500))
    f = rng.normal(1e5, 50.0, (500, 2))
    f[7, 0] = np.nan
    data = MonitoringData(
        {"frc_01": ForceSeries(t, f[:, 0]), "frc_02": ForceSeries(t, f[:, 1])},
        TemperatureSeries(t[::10], rng.normal(5, 1, 50)),
    )
    w = aggregate(data, 60.0)
    for k, tc in enumerate(w.t_ns):
        sel = (t >= tc - 30 * NS) & (t < tc + 30 * NS)
        for c in range(2):
            v = f[sel, c][np.isfinite(f[sel, c])]
            assert w.count[k, c] == len(v)
            np.testing.assert_allclose(w.mean_n[k, c], v.mean(), rtol=1e-12)
            np.testing.assert_allclose(w.std_n[k, c], v.std(ddof=1), rtol=1e-9)
            assert w.max_n[k, c] == v.max()
            assert w.median_n[k, c] == np.median(v)


def test_lowpass_step_response_is_first_order():
    dt, tau = 60.0, 3 * 3600.0
    x = np.r_[np.zeros(10), np.ones(2000)]
    y = lowpass(x, tau, dt)
    k = np.arange(2000)
    # Exact discretization of tau dy/dt = x - y for a sampled step: 1 - exp(-(k + 1) dt / tau).
    np.testing.assert_allclose(y[10:], 1.0 - np.exp(-(k + 1) * dt / tau), atol=1e-12)


def test_gap_sun_covariate_is_zero_at_night_and_peaks_at_solar_noon():
    day = T0 + 71 * 86400 * NS  # 2022-06-21
    t = day + np.arange(0, 86400, 60, dtype=np.int64) * NS
    sun = clear_sky(t)
    assert sun[:60].max() == 0.0  # 00:00-01:00 UTC
    noon_utc_h = (t[np.argmax(sun)] - day) / NS / 3600
    # Solar noon at 11.64 E: 12 h - 11.64/15 h - equation of time (about +1.7 min in late June).
    assert abs(noon_utc_h - (12 - 11.64 / 15 + 1.7 / 60)) < 0.05
    assert 0.98 < sun.max() <= 1.0


def test_cross_validation_recovers_an_exact_linear_effect():
    rng = np.random.default_rng(0)
    n = 3 * 1440
    x = rng.normal(size=(n, 2, 2))
    beta = np.array([2.5, -1.0])
    resid = x @ beta
    valid = np.ones((n, 2), bool)
    fold, kind = folds_of(np.repeat(np.arange(3), 1440), valid)
    r = cross_validate([x], resid, valid, fold)
    assert kind == "day"
    np.testing.assert_allclose(r.beta, beta, rtol=1e-10)
    np.testing.assert_allclose(r.reduction, 1.0, atol=1e-8)


def test_ar1_phi_estimate():
    rng = np.random.default_rng(1)
    e = lfilter([1.0], [1.0, -0.8], rng.standard_normal((20000, 2)), axis=0)
    assert ar1_phi(e) == pytest.approx(0.8, abs=0.02)


def test_placeholder_bearing_sensitivity_is_a_finite_difference():
    s = placeholder_surrogate()
    sens = stiffness_sensitivities(s, path="/nonexistent/surrogate.yaml")["bearing_stiffness"]

    def a_eff(r: float) -> np.ndarray:
        return np.linalg.inv(np.linalg.inv(s.A) + np.eye(2) / ((1 + r) * 2e9))

    h = 1e-6
    np.testing.assert_allclose(sens.dA, (a_eff(h) - a_eff(-h)) / (2 * h), rtol=1e-5)
    du0 = (a_eff(h) - a_eff(-h)) / (2 * h) @ np.linalg.solve(s.A, s.u0)
    np.testing.assert_allclose(sens.du0, du0, rtol=1e-5)


def test_every_vocabulary_effect_has_a_candidate():
    from bridge_shadow.effects import EFFECT_NAMES

    assert tuple(c.name for c in CANDIDATES) == EFFECT_NAMES


def test_clean_record_gives_none():
    dg = diagnose(_record({}), placeholder_surrogate())
    assert dg.summary["best"] == "none"


@pytest.mark.parametrize(("effect", "value"), [("settlement_offset", 7e-4), ("settlement_drift", 2e-4)])
def test_structural_effects_on_numpy_records(effect: str, value: float):
    dg = diagnose(_record({effect: value}), placeholder_surrogate())
    assert dg.summary["best"] == effect
    top = next(c for c in dg.summary["candidates"] if c["effect"] == effect)
    assert top["heldout_reduction"]["total"] >= 0.3


def test_single_channel_drift_and_settlement_drift_are_reported_together():
    dg = diagnose(_record({"sensor_drift": 300.0}), placeholder_surrogate())
    s = dg.summary
    group = [s["best"], *s["indistinguishable_from"]]
    assert set(group) == {"sensor_drift", "settlement_drift"}
    assert "cannot be told apart" in s["statement"]
    # Fewer parameters for the same fit: the single-channel drift is listed first.
    assert s["best"] == "sensor_drift"
    drift = next(c for c in s["candidates"] if c["effect"] == "sensor_drift")
    assert drift["params"]["channel"] == "north"
    assert drift["params"]["d [N/s]"] == pytest.approx(300.0 / 86400.0, rel=0.15)  # 300 N a day, in SI


def test_without_the_shadow_the_posterior_says_it_was_not_computed():
    # The posteriors come from the Shadow pipeline only (one estimator): diagnose() without it
    # must not fall back to a formula of its own.
    dg = diagnose(_record({"settlement_offset": 7e-4}), placeholder_surrogate())
    assert dg.summary["posterior"]["computed"] is False
    assert "before" not in dg.summary["posterior"]


def test_settlement_only_adds_nothing_to_the_model_so_after_equals_before():
    # Settlements are what the shadow estimates: with only an offset named, "after" is "before"
    # (the shadow run once), and both are the shadow's answer, near the true offset.
    from bridge_shadow.estimate import load_config

    data = _record({"settlement_offset": 7e-4}, days=1)
    # one sample per window here, so the shadow must accept windows of one sample
    cfg = load_config(overrides={"window_min_samples": 1, "checkpoint_path": ""})
    dg = diagnose(data, placeholder_surrogate(), shadow=True, shadow_config=cfg)
    post = dg.summary["posterior"]
    assert dg.summary["best"] == "settlement_offset"
    assert post["after"]["effects_added"] == []
    assert post["after"]["mean_m"] == post["before"]["mean_m"]
    np.testing.assert_allclose(post["before"]["mean_m"], [7e-4, -7e-4], atol=5e-5)


def test_too_short_record_is_a_typed_error():
    data = _record({}, days=1)
    cut = MonitoringData(
        {k: ForceSeries(v.stamp_ns[:3], v.force_n[:3]) for k, v in data.forces.items()}, data.temperature
    )
    with pytest.raises(GapError):
        diagnose(cut, placeholder_surrogate())

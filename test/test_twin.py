"""Truth twin: sun closed forms, determinism, March weather statistics, noise, and every effect."""

from __future__ import annotations

import csv
import datetime as dt
from zoneinfo import ZoneInfo

import numpy as np
import pytest
from scipy.signal import lfilter

from bridge_shadow.effects import EFFECT_NAMES, EFFECTS
from bridge_shadow.errors import InputError
from bridge_shadow.model.surrogate_file import placeholder_surrogate
from bridge_shadow.sun import LAT_DEG, clear_sky, solar_elevation_deg
from bridge_shadow.twin.config import TwinConfig, ou_time_constant_for_window_phi, window_phi
from bridge_shadow.twin.response import two_span_mid_influence
from bridge_shadow.twin.simulate import parse_effects, simulate

NS = 1_000_000_000
BERLIN = ZoneInfo("Europe/Berlin")
SUR = placeholder_surrogate()


def _ns(*args: int) -> int:
    return int(dt.datetime(*args, tzinfo=dt.timezone.utc).timestamp()) * NS


def _day_minutes(y: int, m: int, d: int) -> np.ndarray:
    return _ns(y, m, d) + np.arange(1440, dtype=np.int64) * 60 * NS


# --- sun -------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("date", "declination"),
    [((2022, 3, 20), -0.1), ((2022, 6, 21), 23.44), ((2022, 12, 21), -23.44)],
)
def test_noon_elevation_is_90_minus_latitude_plus_declination(date: tuple, declination: float) -> None:
    el = solar_elevation_deg(_day_minutes(*date))
    assert el.max() == pytest.approx(90.0 - LAT_DEG + declination, abs=0.3)


def test_solar_noon_at_neubiberg_in_march() -> None:
    # Mean solar noon at 11.64 E is 11:13.4 UTC; the equation of time on 20 March is -7.5 min.
    t = _day_minutes(2022, 3, 20)
    noon_utc_min = np.argmax(solar_elevation_deg(t))
    assert noon_utc_min == pytest.approx(11 * 60 + 13.4 + 7.5, abs=2)


def test_clear_sky_is_zero_at_night_and_one_at_the_june_noon() -> None:
    june = clear_sky(_day_minutes(2022, 6, 21))
    march = clear_sky(_day_minutes(2022, 3, 14))
    assert june.max() == pytest.approx(1.0, abs=2e-3)
    assert 0.6 < march.max() < 0.8
    assert march[0] == 0.0 and march[23 * 60] == 0.0  # midnight and 23:00 UTC
    assert np.all((march >= 0.0) & (march <= 1.0))
    assert np.count_nonzero(march) / 1440 == pytest.approx(0.5, abs=0.03)  # ~12 h of day near the equinox


# --- config closed forms ---------------------------------------------------------------------------


def test_window_phi_inverts() -> None:
    tau = ou_time_constant_for_window_phi(0.9, 60.0)
    assert window_phi(60.0, tau) == pytest.approx(0.9, rel=1e-9)
    # small-window limit: phi -> 1 - 2 W / (3 tau)
    assert window_phi(1.0, 1e4) == pytest.approx(1.0 - 2.0 / 3e4, rel=1e-8)


def test_two_span_influence_line() -> None:
    span = 15.0
    p = np.array([-1.0, 0.0, 7.5, 15.0, 22.5, 30.0, 31.0])
    r = two_span_mid_influence(p, span)
    assert r == pytest.approx([0.0, 0.0, 0.6875, 1.0, 0.6875, 0.0, 0.0])
    # Maxwell-Betti: the area under the influence line is R_mid of a unit uniform load, 5 L / 4.
    x = np.linspace(0.0, 2 * span, 200_001)
    assert np.trapezoid(two_span_mid_influence(x, span), x) == pytest.approx(1.25 * span, rel=1e-6)


# --- determinism, stamps, data loss ----------------------------------------------------------------


def _arrays(data) -> list[np.ndarray]:
    out = []
    for s in data.forces.values():
        out += [s.stamp_ns, s.force_n]
    return [*out, data.temperature.stamp_ns, data.temperature.temp_c]


def test_same_seed_same_arrays_other_seed_other_arrays() -> None:
    kw = dict(days=0.5, rate_hz=0.2, effects={"traffic": 2.5e4, "vertical_gradient": 4.0}, surrogate=SUR)
    a, _ = simulate(seed=5, **kw)
    b, _ = simulate(seed=5, **kw)
    c, _ = simulate(seed=6, **kw)
    for x, y in zip(_arrays(a), _arrays(b), strict=True):
        np.testing.assert_allclose(x, y, rtol=1e-12, atol=0)  # a simulation rebuilt: same to rounding
    fa, fc = a.forces["frc_01"].force_n, c.forces["frc_01"].force_n
    n = min(len(fa), len(fc))
    assert not np.allclose(fa[:n], fc[:n], equal_nan=True)


def test_default_start_stamps_and_data_loss() -> None:
    data, truth = simulate(days=2.0, rate_hz=0.1, seed=1, surrogate=SUR)
    start = dt.datetime(2022, 3, 14, tzinfo=BERLIN)
    assert truth["start_ns"] == int(start.timestamp()) * NS == 1_647_212_400 * NS
    n = truth["counts"]["force_samples"]
    assert n == 2 * 86400 // 10
    for s in data.forces.values():
        assert s.stamp_ns[0] >= truth["start_ns"]
        assert np.all(np.diff(s.stamp_ns) >= 10 * NS)  # strictly increasing, on the 10 s grid
        assert np.all((s.stamp_ns - truth["start_ns"]) % (10 * NS) == 0)
        assert 0 < n - len(s) < n // 10  # some dropouts, not many
        assert np.isnan(s.force_n).sum() >= 3  # a few NaN readings for the gate
        assert np.all(np.isfinite(s.force_n) | np.isnan(s.force_n))
    temp = data.temperature
    assert np.isnan(temp.temp_c).sum() >= 1
    assert len(temp) <= 2 * 1440
    assert np.all(temp.variance == pytest.approx(0.05**2))


def test_effect_names_are_validated() -> None:
    with pytest.raises(InputError, match="valid effects: settlement_offset"):
        parse_effects(["scour=1"])
    with pytest.raises(InputError, match="NAME=VALUE"):
        parse_effects(["settlement_offset"])
    with pytest.raises(InputError, match="not a number"):
        parse_effects(["traffic=heavy"])
    with pytest.raises(InputError, match="twice"):
        parse_effects(["traffic=1", "traffic=2"])
    assert parse_effects(["traffic=2.5e4", "settlement_offset=7e-4"]) == {
        "settlement_offset": 7e-4,
        "traffic": 2.5e4,
    }


# --- March weather against the real record --------------------------------------------------------


def _march_csv(munich_data) -> dict[str, np.ndarray]:
    with open(munich_data / "Weather" / "TemperatureComparisonMUC.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    tmin = np.array([float(r["TMinB"]) for r in rows])
    tmax = np.array([float(r["TMaxB"]) for r in rows])
    return {"tmin": tmin, "tmax": tmax, "swing": tmax - tmin}


@pytest.mark.realdata
def test_air_temperature_matches_march_2022_at_the_bridge(munich_data) -> None:
    real = _march_csv(munich_data)
    assert real["swing"].mean() == pytest.approx(16.6, abs=0.05)  # DESIGN 3
    swings, mids, lows, highs = [], [], [], []
    for seed in range(8):
        data, _ = simulate(days=20, rate_hz=1 / 3600, seed=seed, start="2022-03-12T00:00", surrogate=SUR)
        t = data.temperature
        local_day = (t.stamp_ns // NS + 3600) // 86400  # CET (no DST before 27 March)
        ok = np.isfinite(t.temp_c)
        days = np.unique(local_day[ok])[:19]  # whole local days before the DST switch
        tmax = np.array([t.temp_c[ok & (local_day == d)].max() for d in days])
        tmin = np.array([t.temp_c[ok & (local_day == d)].min() for d in days])
        swings.append(tmax - tmin)
        mids.append((tmax + tmin) / 2)
        lows.append(tmin.min())
        highs.append(tmax.max())
    swings, mids = np.concatenate(swings), np.concatenate(mids)
    real_mid = (real["tmin"] + real["tmax"]) / 2
    assert swings.mean() == pytest.approx(real["swing"].mean(), abs=2.0)
    # overcast and clear days, as in the real record (20 % below 10 K, 40 % above 20 K)
    assert 0.02 < np.mean(swings < 10.0) < 0.45 and 0.15 < np.mean(swings > 20.0) < 0.65
    assert swings.max() < 27.0 and swings.min() > 2.0
    assert mids.mean() == pytest.approx(real_mid.mean(), abs=1.0)
    assert mids.std() == pytest.approx(real_mid.std(), rel=0.5)
    assert np.median(lows) == pytest.approx(real["tmin"].min(), abs=3.0)  # -6.0 C
    assert np.median(highs) == pytest.approx(real["tmax"].max(), abs=3.0)  # 20.7 C


def test_daily_maximum_in_the_afternoon_minimum_near_dawn() -> None:
    _, truth = simulate(days=6, rate_hz=1 / 300, seed=4, surrogate=SUR)
    s = truth["series"]
    hours = ((s["stamp_ns"] // NS + 3600) % 86400) / 3600  # CET
    temp = s["air_temp_c"].reshape(6, -1)
    h = hours.reshape(6, -1)
    t_max = h[np.arange(6), temp.argmax(axis=1)]
    t_min = h[np.arange(6), temp.argmin(axis=1)]
    assert np.median(t_max) == pytest.approx(15.0, abs=1.5)
    assert np.median(t_min) == pytest.approx(6.5, abs=1.5)


# --- sensor noise -------------------------------------------------------------------------------


def _window_means(t_ns: np.ndarray, y: np.ndarray, width_s: float = 60.0) -> np.ndarray:
    k = (t_ns - t_ns[0]) // int(width_s * NS)
    ok = np.isfinite(y)
    sums = np.bincount(k[ok], y[ok], minlength=k.max() + 1)
    counts = np.bincount(k[ok], minlength=k.max() + 1)
    means = np.full(len(sums), np.nan)
    means[counts > 0] = sums[counts > 0] / counts[counts > 0]
    return means


def test_noise_sigma_and_ar1_of_60s_means() -> None:
    data, truth = simulate(days=3, rate_hz=1.0, seed=7, surrogate=SUR)
    s = truth["series"]
    for i, ch in enumerate(("frc_01", "frc_02")):
        f = data.forces[ch]
        idx = np.searchsorted(s["stamp_ns"], f.stamp_ns)
        resid = f.force_n - s["clean_force_n"][idx, i]  # measured minus noise-free
        assert np.nanstd(resid) == pytest.approx(TwinConfig().noise_sd_n[i], rel=0.1)
        m = _window_means(f.stamp_ns, resid)
        ok = np.isfinite(m[:-1]) & np.isfinite(m[1:])
        phi = np.corrcoef(m[:-1][ok], m[1:][ok])[0, 1]
        assert phi == pytest.approx(0.9, abs=0.04)
        lag1_raw = np.corrcoef(
            resid[:-1][np.isfinite(resid[:-1] + resid[1:])], resid[1:][np.isfinite(resid[:-1] + resid[1:])]
        )[0, 1]
        assert 0.8 < lag1_raw < 0.95  # 1 Hz samples: OU part near 1, diluted by the white part


# --- each effect does what its definition says -----------------------------------------------------


def _pair(effects: dict[str, float], days: float = 1.0, rate_hz: float = 0.1, seed: int = 11):
    """Measured effect-minus-baseline forces per channel; one seed gives identical stamps and noise."""
    base, tb = simulate(days=days, rate_hz=rate_hz, seed=seed, surrogate=SUR)
    eff, te = simulate(days=days, rate_hz=rate_hz, seed=seed, effects=effects, surrogate=SUR)
    np.testing.assert_allclose(eff.temperature.temp_c, base.temperature.temp_c, rtol=1e-12, atol=0)
    diff = {}
    for ch in ("frc_01", "frc_02"):
        np.testing.assert_array_equal(eff.forces[ch].stamp_ns, base.forces[ch].stamp_ns)  # integer ns
        ok = np.isfinite(base.forces[ch].force_n)
        diff[ch] = (base.forces[ch].stamp_ns[ok], eff.forces[ch].force_n[ok] - base.forces[ch].force_n[ok])
    return tb, te, diff


def _full_pair(effects: dict[str, float], days: float = 1.0, rate_hz: float = 0.1, seed: int = 11):
    """Noise-free effect-minus-baseline force difference on the full sample grid, (n, 2) N."""
    _, tb = simulate(days=days, rate_hz=rate_hz, seed=seed, surrogate=SUR)
    _, te = simulate(days=days, rate_hz=rate_hz, seed=seed, effects=effects, surrogate=SUR)
    np.testing.assert_allclose(te["series"]["noise_n"], tb["series"]["noise_n"], rtol=1e-12, atol=0)
    measured_diff = (
        te["series"]["clean_force_n"]
        + te["series"]["drift_n"]
        - tb["series"]["clean_force_n"]
        - tb["series"]["drift_n"]
    )
    return tb, te, measured_diff


def test_baseline_is_dead_load_plus_noise() -> None:
    _, tb = simulate(days=1, rate_hz=0.1, seed=2, surrogate=SUR)
    s = tb["series"]
    np.testing.assert_allclose(
        s["clean_force_n"], np.broadcast_to(SUR.u0, s["clean_force_n"].shape), rtol=1e-12
    )
    assert tb["settlement"] == {"mean_m": [0.0, 0.0], "start_m": [0.0, 0.0], "end_m": [0.0, 0.0]}


def test_settlement_offset_shifts_window_means_by_A_x() -> None:
    v = EFFECTS["settlement_offset"].realistic
    data, truth = simulate(days=1, rate_hz=1.0, seed=3, effects={"settlement_offset": v}, surrogate=SUR)
    shift = SUR.A @ np.array([v, -v])
    assert abs(shift[0]) > 1e3  # kN-sized, as in the paper
    for i, ch in enumerate(("frc_01", "frc_02")):
        f = data.forces[ch]
        m = _window_means(f.stamp_ns, f.force_n)
        # 1440 windows with phi = 0.9: the mean has sd about 55 N / sqrt(1440 / 19), ~ 6 N
        assert np.nanmean(m) - SUR.u0[i] == pytest.approx(shift[i], abs=30.0)
    assert truth["settlement"]["mean_m"] == pytest.approx([v, -v])
    _, _, diff = _pair({"settlement_offset": v})
    for i, ch in enumerate(("frc_01", "frc_02")):
        np.testing.assert_allclose(diff[ch][1], shift[i], rtol=1e-9)


def test_settlement_drift_south_sinks_linearly() -> None:
    v = EFFECTS["settlement_drift"].realistic
    tb, te, diff = _full_pair({"settlement_drift": v}, days=2)
    t_day = (tb["series"]["stamp_ns"] - tb["start_ns"]) / (86400 * NS)
    x = np.column_stack([-v * t_day, np.zeros_like(t_day)])
    np.testing.assert_allclose(diff, x @ SUR.A.T, rtol=1e-9, atol=1e-6)
    assert te["settlement"]["start_m"] == [0.0, 0.0]
    assert te["settlement"]["end_m"][0] == pytest.approx(-v * 2.0, rel=1e-3)
    assert te["settlement"]["mean_m"][0] == pytest.approx(-v * 1.0, rel=1e-3)


def test_settlement_step() -> None:
    _, te = simulate(days=1, rate_hz=0.1, seed=1, steps=[(0.5, -2e-4, 1e-4)], surrogate=SUR)
    x = te["series"]["x_m"]
    n = len(x)
    assert np.all(x[: n // 2] == 0.0) and np.all(x[n // 2 :] == [-2e-4, 1e-4])  # exact: the step as set


def test_uniform_temperature_follows_the_air() -> None:
    c = EFFECTS["uniform_temperature"].realistic
    tb, _te, diff = _full_pair({"uniform_temperature": c})
    air = tb["series"]["air_temp_c"]
    np.testing.assert_allclose(diff, np.outer(air - tb["t_ref_c"], [c, c]), rtol=1e-9, atol=1e-6)
    assert tb["t_ref_c"] == pytest.approx(air.mean(), abs=0.05)  # mean air temperature of the record
    assert np.ptp(diff[:, 0]) > 5 * c  # a diurnal swing of several K


@pytest.mark.parametrize("name", ["vertical_gradient", "transverse_gradient"])
def test_sun_driven_gradients(name: str) -> None:
    g = EFFECTS[name].realistic
    tb, _te, diff = _full_pair({name: g}, days=2)
    s = tb["series"]
    sun = clear_sky(s["stamp_ns"])  # recomputed here, not taken from the twin
    expected = np.outer(g * sun * s["clearness"], SUR.thermal[name])
    np.testing.assert_allclose(diff, expected, rtol=1e-9, atol=1e-6)
    np.testing.assert_allclose(diff[sun == 0.0], 0.0, atol=1e-6)  # nothing at night (two runs' difference)
    clearness = np.asarray(tb["weather"]["clearness"])
    assert np.all((clearness >= 0.0) & (clearness <= 1.0))


def test_thermal_lag_is_air_minus_first_order_lagged_air() -> None:
    tau_h = EFFECTS["thermal_lag"].realistic
    tb, _te, diff = _full_pair({"thermal_lag": tau_h}, days=2, rate_hz=0.1)
    air = tb["series"]["air_temp_c"]
    a = np.exp(-10.0 / (tau_h * 3600.0))
    lagged = lfilter([1 - a], [1, -a], air, zi=[a * air[0]])[0]  # independent discretization
    expected = np.outer(air - lagged, SUR.thermal["vertical_gradient"])
    late = slice(len(air) // 3, None)  # after 16 h = 5 tau the start-up is gone
    scale = np.abs(expected[late]).max()
    assert scale > 1e3  # about 1 kN from a few K between deck and bulk
    np.testing.assert_allclose(diff[late], expected[late], atol=0.02 * scale)


def test_bearing_stiffness_changes_u0_by_the_series_spring() -> None:
    r = EFFECTS["bearing_stiffness"].realistic
    _tb, te, diff = _full_pair({"bearing_stiffness": r})
    k_b = 2.0e9
    a_eff = np.linalg.inv(np.linalg.inv(SUR.A) + np.eye(2) / k_b)
    du0 = a_eff @ a_eff / k_b @ np.linalg.inv(SUR.A) @ SUR.u0
    np.testing.assert_allclose(diff, np.broadcast_to(r * du0, diff.shape), rtol=1e-9)
    assert np.all(diff < 0)  # softer bearings: less load on the central support
    assert np.allclose(te["surrogate"]["u0"], SUR.u0 + r * du0)


def test_connector_stiffness_scales_the_settlement_response() -> None:
    r, v = EFFECTS["connector_stiffness"].realistic, 7e-4
    _tb, _te, diff = _full_pair({"settlement_offset": v, "connector_stiffness": r})
    shift = (1 + 0.3 * r) * SUR.A @ np.array([v, -v])
    np.testing.assert_allclose(diff, np.broadcast_to(shift, diff.shape), rtol=1e-9)


def test_sensor_drift_on_the_north_cell_only() -> None:
    d = EFFECTS["sensor_drift"].realistic
    tb, _te, diff = _pair({"sensor_drift": d}, days=2)
    t_ns, north = diff["frc_02"]
    np.testing.assert_allclose(north, d * (t_ns - tb["start_ns"]) / (86400 * NS), rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(diff["frc_01"][1], 0.0, atol=1e-6)  # two runs' difference, N


def test_traffic_crossings_in_daytime_with_the_influence_line() -> None:
    w = EFFECTS["traffic"].realistic
    tb, te, diff = _full_pair({"traffic": w}, days=2, rate_hz=1.0)
    t = tb["series"]["stamp_ns"]
    hours = dt_local_hours(t)
    on = np.abs(diff).sum(axis=1) > 0
    assert np.all((hours[on] >= 8.0) & (hours[on] <= 18.01))
    assert 60 < te["counts"]["crossings"] < 180  # 6 per hour, 10 h a day, 2 days
    total = diff.sum(axis=1)
    assert total.max() == pytest.approx(w, rel=0.03)  # a car over the central support
    assert total.max() <= w * (1 + 1e-9)
    assert diff.max() == pytest.approx(w / 2, rel=0.3)  # about +12 kN per bearing (DESIGN 3)
    assert np.all(diff >= 0.0)
    # a 10 s crossing lasts 8-12 samples at 1 Hz
    runs = np.diff(np.flatnonzero(np.diff(on.astype(int)) != 0))[::2]
    assert 6 <= np.median(runs) <= 13


def dt_local_hours(t_ns: np.ndarray) -> np.ndarray:
    """Local (Europe/Berlin) hour of day for stamps in March before the DST switch (CET)."""
    return ((t_ns // NS + 3600) % 86400) / 3600


def test_every_effect_of_the_vocabulary_changes_the_forces() -> None:
    for name in EFFECT_NAMES:
        effects = {name: EFFECTS[name].realistic}
        if name == "connector_stiffness":
            effects["settlement_offset"] = 7e-4  # no settlement, no signature with the placeholder
        base_fx = {"settlement_offset": 7e-4} if name == "connector_stiffness" else {}
        _, tb = simulate(days=1, rate_hz=0.05, seed=0, effects=base_fx, surrogate=SUR)
        _, te = simulate(days=1, rate_hz=0.05, seed=0, effects=effects, surrogate=SUR)
        d = (
            te["series"]["clean_force_n"]
            + te["series"]["drift_n"]
            - tb["series"]["clean_force_n"]
            - tb["series"]["drift_n"]
        )
        assert np.abs(d).max() > 100.0, name  # well above the noise of a 60 s mean


@pytest.mark.parametrize("style", ["A", "dA"])
def test_stiffness_sensitivities_from_the_surrogate_file_block(style: str) -> None:
    d = "d" if style == "dA" else ""
    block = {
        "relative_step": 0.05,
        "bearing_stiffness": {
            f"{d}A": [[1e5, 0.0], [0.0, 1e5]],
            f"{d}u0": [2e3, 1e3],
            f"{d}thermal": {"vertical_gradient": [10.0, 20.0]},
        },
    }
    r, v = -0.5, 7e-4
    kw = dict(days=0.2, rate_hz=0.1, seed=1, surrogate=SUR, sensitivities_block=block)
    _, tb = simulate(effects={"settlement_offset": v}, **kw)
    _, te = simulate(effects={"settlement_offset": v, "bearing_stiffness": r}, **kw)
    assert te["sensitivities"]["bearing_stiffness"]["source"] == "surrogate sensitivities"
    assert te["sensitivities"]["connector_stiffness"]["source"] == "closed-form placeholder"
    diff = te["series"]["clean_force_n"] - tb["series"]["clean_force_n"]
    expected = r * (np.array([2e3, 1e3]) + 1e5 * np.array([v, -v]))
    np.testing.assert_allclose(diff, np.broadcast_to(expected, diff.shape), rtol=1e-9)


@pytest.mark.parametrize(
    ("start", "expected_s"),
    [
        ("2022-03-14T00:00", 1_647_212_400.0),  # naive: Europe/Berlin (CET)
        ("2022-04-11T08:36:00.25", 1_649_658_960.25),  # CEST: 06:36 UTC
        ("2022-03-14T00:00:00.5+00:00", 1_647_216_000.5),
    ],
)
def test_start_stamp(start: str, expected_s: float) -> None:
    data, truth = simulate(days=0.01, rate_hz=0.1, seed=0, start=start, surrogate=SUR)
    assert truth["start_ns"] == round(expected_s * 1e6) * 1000
    assert data.forces["frc_01"].stamp_ns[0] == truth["start_ns"]  # no dropout in 0.01 day
    ns = 1_647_216_000_123_456_789
    assert simulate(days=0.01, rate_hz=0.1, seed=0, start=ns, surrogate=SUR)[1]["start_ns"] == ns

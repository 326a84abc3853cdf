"""Shadow pipeline: gating of every bad input, chunking invariance, checkpoint and resume, loud failures."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bridge_shadow.contract import CHANNELS
from bridge_shadow.errors import ConfigError
from bridge_shadow.estimate import REASONS, Shadow, ShadowConfig, load_config
from bridge_shadow.model.surrogate_file import placeholder_surrogate
from bridge_shadow.series import ForceSeries, MonitoringData, TemperatureSeries

T0 = 1_700_000_040 * 10**9  # a window boundary (divisible by 60 s)
S = 10**9


def synthetic(minutes: int = 90, rate: int = 5, seed: int = 0, x_m=(4e-4, -3e-4)) -> MonitoringData:
    """Forces with a temperature effect (S 300 N/K, N 80 N/K) and AR(1) noise; 1 Hz temperature."""
    sur = placeholder_surrogate()
    rng = np.random.default_rng(seed)
    n = minutes * 60 * rate
    stamps = T0 + np.arange(n, dtype=np.int64) * (S // rate)
    t_stamps = T0 + np.arange(minutes * 60, dtype=np.int64) * S
    temp = 8.0 + 6.0 * np.sin(2 * np.pi * np.arange(minutes * 60) / 7200.0)
    t_at = np.interp(stamps, t_stamps, temp)
    noise = np.zeros((n, 2))
    e = rng.normal(0.0, 120.0, (n, 2))
    for i in range(1, n):
        noise[i] = 0.9 * noise[i - 1] + e[i]
    forces = sur.reactions(np.array(x_m)) + np.c_[300.0 * (t_at - 8.0), 80.0 * (t_at - 8.0)] + noise
    return MonitoringData.from_arrays(stamps, forces, t_stamps, temp)


def small_config(**kw) -> ShadowConfig:
    base = dict(
        warmup_windows=10,
        spline_segments=6,
        spline_t_min_c=0.0,
        spline_t_max_c=20.0,
    )
    base.update(kw)
    return ShadowConfig(**base)


def test_shipped_parameter_file_equals_the_defaults(root: Path) -> None:
    assert load_config(root / "config" / "shadow.yaml") == ShadowConfig()
    with pytest.raises(ConfigError):
        ShadowConfig.from_params({"window_s": 60.0, "windw_s": 1.0})
    with pytest.raises(ConfigError):
        ShadowConfig(smoothing="magic")


@pytest.mark.parametrize("smoothing", ["reml", "gcv", "fixed"])
def test_chunking_does_not_change_the_posterior(smoothing: str) -> None:
    data = synthetic(minutes=40, rate=2)
    cfg = small_config(smoothing=smoothing)
    ref = Shadow(cfg, placeholder_surrogate()).run(data, chunk=1)
    for chunk in (7, 1000, 10**7):
        res = Shadow(cfg, placeholder_surrogate()).run(data, chunk=chunk)
        assert np.allclose(res.mean_m, ref.mean_m, rtol=1e-12, atol=0.0)
        assert np.allclose(res.covariance_m2, ref.covariance_m2, rtol=1e-12, atol=0.0)
        assert res.updates == ref.updates >= 35
        np.testing.assert_allclose(
            [o.mean_m for o in res.outputs], [o.mean_m for o in ref.outputs], rtol=1e-10, atol=1e-15
        )


def test_resume_from_checkpoint_equals_an_uninterrupted_run(tmp_path: Path) -> None:
    data = synthetic(minutes=60, rate=2, seed=3)
    # a settlement step at minute 40, so that an event and two segments cross the checkpoint too
    for c, ch in enumerate(CHANNELS):
        f = data.forces[ch]
        f.force_n[f.stamp_ns >= T0 + 40 * 60 * S] += placeholder_surrogate().A[c] @ np.array([-1e-3, -1e-3])
    # and a dead north cell over minutes 20-23, so that rejected windows come before the checkpoint
    north = data.forces["frc_02"]
    north.force_n[(north.stamp_ns >= T0 + 20 * 60 * S) & (north.stamp_ns < T0 + 23 * 60 * S)] = np.nan
    cfg = small_config(
        checkpoint_path=str(tmp_path / "shadow.npz"), checkpoint_period_s=300.0, refit_windows=7
    )
    whole = Shadow(cfg, placeholder_surrogate()).run(data)
    assert len(whole.events) == 1
    for cut in (60 * 12, 60 * 5 * 41):  # mid warm-up; while the step's windows are held
        a = Shadow(cfg, placeholder_surrogate())
        a.run(_slice(data, 0, cut), flush=False)
        a.save_checkpoint()
        assert (tmp_path / "shadow.npz").is_file() and not list(tmp_path.glob("*.tmp"))
        b = Shadow.resume(tmp_path / "shadow.npz")
        res = b.run(_slice(data, cut, None))
        np.testing.assert_allclose(res.mean_m, whole.mean_m, rtol=1e-10, atol=0.0)
        np.testing.assert_allclose(res.covariance_m2, whole.covariance_m2, rtol=1e-10, atol=0.0)
        assert b.rejected == whole.rejected and len(res.events) == 1
        # every rejected window, those before the checkpoint too (the shadow's log, not the outputs)
        assert res.rejected_windows() == whole.rejected_windows() != []
        assert res.events[0].window == whole.events[0].window
        assert b.spline_info()["frc_01"]["edf"] == pytest.approx(whole.spline["frc_01"]["edf"], rel=1e-10)


def _slice(data: MonitoringData, lo: int, hi: int | None) -> MonitoringData:
    """Messages lo:hi in log-time order across the three topics."""
    logs = np.concatenate(
        [data.forces["frc_01"].log_ns, data.forces["frc_02"].log_ns, data.temperature.log_ns]
    )
    cut_lo = np.sort(logs, kind="stable")[lo]
    cut_hi = np.sort(logs, kind="stable")[hi] if hi is not None else None

    def sel(log: np.ndarray) -> np.ndarray:
        return (log >= cut_lo) & (log < cut_hi if cut_hi is not None else True)

    return data.select(sel, by="log_ns")


def test_every_bad_input_is_dropped_and_counted() -> None:
    rate, minutes = 5, 40
    data = synthetic(minutes=minutes, rate=rate, seed=1)
    f1, f2, tmp = data.forces["frc_01"], data.forces["frc_02"], data.temperature
    s1, v1 = list(f1.stamp_ns), list(f1.force_n)
    fr1, lg1 = list(f1.frame_id), list(f1.log_ns)

    def minute(m: float) -> int:
        return int(m * 60 * rate)

    # frc_01 in minute 12: NaN, inf, negative, absurd, wrong frame, duplicate, out of order, clock jump
    i = minute(12.5)
    bad = [
        (s1[i] + 1, np.nan, "frc_01"),
        (s1[i] + 2, np.inf, "frc_01"),
        (s1[i] + 3, -5.0, "frc_01"),
        (s1[i] + 4, 1e9, "frc_01"),
        (s1[i] + 5, v1[i], "frc_02"),
        (s1[i], v1[i], "frc_01"),
        (s1[i] - S, v1[i], "frc_01"),
        (s1[i] + 2 * 86400 * S, v1[i], "frc_01"),
    ]
    for k, (st, val, fr) in enumerate(bad):
        s1.insert(i + 1 + k, st)
        v1.insert(i + 1 + k, val)
        fr1.insert(i + 1 + k, fr)
        lg1.insert(i + 1 + k, s1[i])
    f1 = ForceSeries(np.array(s1), np.array(v1), np.array(fr1, dtype=object), np.array(lg1))
    # minute 15: both forces +40 kN for the whole window -> Mahalanobis outlier
    m15 = (f1.stamp_ns >= T0 + 15 * 60 * S) & (f1.stamp_ns < T0 + 16 * 60 * S)
    f1.force_n[m15] += 40e3
    m15b = (f2.stamp_ns >= T0 + 15 * 60 * S) & (f2.stamp_ns < T0 + 16 * 60 * S)
    f2.force_n[m15b] += 40e3
    # minute 22: frc_02 keeps only 2 samples (< window_min_samples = 3) -> sparse window
    m22 = (f2.stamp_ns >= T0 + 22 * 60 * S + 2 * (S // rate)) & (f2.stamp_ns < T0 + 23 * 60 * S)
    # minutes 26-30: frc_02 silent -> missing topic (5 windows), except its first 10 s of
    # minute 29, which arrive after frc_01 has moved on (log time 30.9 min): late
    m26 = (f2.stamp_ns >= T0 + 26 * 60 * S) & (f2.stamp_ns < T0 + 29 * 60 * S)
    m26 |= (f2.stamp_ns >= T0 + 29 * 60 * S + 10 * S) & (f2.stamp_ns < T0 + 31 * 60 * S)
    keep2 = ~(m22 | m26)
    log2 = f2.log_ns.copy()
    delayed = (f2.stamp_ns >= T0 + 29 * 60 * S) & (f2.stamp_ns < T0 + 29 * 60 * S + 10 * S)
    log2[delayed] = T0 + int(30.9 * 60 * S)
    f2 = ForceSeries(f2.stamp_ns[keep2], f2.force_n[keep2], f2.frame_id[keep2], log2[keep2])
    # temperature: a 300 s hole from 16.5 to 21.5 min (stale),
    # one NaN, one out of range, one wrong frame
    tkeep = ~((tmp.stamp_ns > T0 + 990 * S) & (tmp.stamp_ns < T0 + 1290 * S))
    tv = tmp.temp_c.copy()
    tv[100], tv[200] = np.nan, 150.0
    tframe = tmp.frame_id.copy()
    tframe[300] = "wrong"
    temp = TemperatureSeries(tmp.stamp_ns[tkeep], tv[tkeep], None, tframe[tkeep])
    data = MonitoringData({"frc_01": f1, "frc_02": f2}, temp)

    # late samples are the front end's business: the traffic screen would hold this short record
    shadow = Shadow(small_config(traffic_hold_s=0.0), placeholder_surrogate())
    res = shadow.run(data, chunk=50)
    rej = res.rejected
    expected = {
        "nonfinite": 3,
        "out_of_range": 3,
        "frame_id": 2,
        "duplicate": 1,
        "out_of_order": 1,
        "clock_jump": 1,
        "late": 10 * rate,
        "missing_topic": 5,
        "sparse_window": 1,
        "outlier": 1,
    }
    for reason, count in expected.items():
        assert rej[reason] == count, (reason, rej)
    # windows 18, 19 have samples > 120 s from any reading: used, stale (their compensation widened,
    # not skipped); window 20 waits (up to the 120 s temperature horizon) for the reading at
    # 21.5 min, 30-90 s from its forces: not stale
    assert rej["stale_temperature"] == 0 and res.stale_temperature_windows == 2
    assert res.to_json()["windows"]["stale_temperature"] == 2
    assert any(w.startswith("stale air temperature: 2 windows") for w in res.warnings)
    reasons = {o.index - res.outputs[0].index: o.reason for o in res.outputs if o.reason}
    assert reasons == {
        15: "outlier",
        22: "sparse_window",
        **dict.fromkeys(range(26, 31), "missing_topic"),
    }
    assert set(rej) == set(REASONS)
    assert np.all(np.isfinite(res.mean_m)) and np.all(np.isfinite(res.covariance_m2))
    assert res.updates > 20
    diag = shadow.diagnostics()
    assert diag["level"] in ("OK", "WARN") and diag["rejected"] == rej


def test_without_temperature_the_shadow_runs_uncompensated_and_says_so() -> None:
    data = synthetic(minutes=20, rate=2)
    empty = TemperatureSeries(np.empty(0, np.int64), np.empty(0))
    shadow = Shadow(small_config(), placeholder_surrogate())
    res = shadow.run(MonitoringData(data.forces, empty))
    assert res.updates == 20 and res.uncompensated_windows == 20 and res.rejected["stale_temperature"] == 0
    assert np.all(np.sqrt(np.diag(res.covariance_m2)) < 0.5 * shadow.prior_sigma_m)  # the data moved it
    assert any("no air temperature" in w for w in res.warnings)
    diag = shadow.diagnostics()
    assert diag["level"] == "WARN" and "no air temperature" in diag["message"]
    assert res.to_json()["windows"]["uncompensated"] == 20


def test_a_topic_rejected_message_by_message_is_named_with_its_reason() -> None:
    data = synthetic(minutes=20, rate=2)
    t = data.temperature
    wrong = TemperatureSeries(t.stamp_ns, t.temp_c, None, np.full(len(t), "weather_station", dtype=object))
    res = Shadow(small_config(), placeholder_surrogate()).run(MonitoringData(data.forces, wrong))
    line = [w for w in res.warnings if "air_temperature" in w and "all" in w]
    assert line and "frame_id 'weather_station'" in line[0] and "expected 'air_temperature'" in line[0]
    # the frame id is a parameter; empty accepts any
    any_frame = Shadow(small_config(temperature_frame_id=""), placeholder_surrogate())
    ok = any_frame.run(MonitoringData(data.forces, wrong))
    assert ok.updates == 20 and not ok.warnings
    named = Shadow(small_config(temperature_frame_id="weather_station"), placeholder_surrogate())
    assert named.run(MonitoringData(data.forces, wrong)).rejected["frame_id"] == 0


def test_compensated_settlement_recovers_the_truth() -> None:
    x_true = np.array([4e-4, -3e-4])
    data = synthetic(minutes=240, rate=2, seed=5, x_m=x_true)
    # the temperature swings around 8 C over whole periods: the record's mean level is the truth's
    shadow = Shadow(ShadowConfig(), placeholder_surrogate())
    res = shadow.run(data)
    sd = np.sqrt(np.diag(res.covariance_m2))
    assert np.all(np.abs(res.mean_m - x_true) < 4 * sd), (res.mean_m, sd)
    assert np.all(sd < 3e-5)  # data, not the prior, decide
    assert 0.5 <= res.spline["frc_01"]["edf"] < 10.0 and not res.events
    # the curve follows 300 N/K (south) and 80 N/K (north) around the record's mean temperature
    g = shadow.compensation.curve(shadow.fit, np.array([[6.0, 6.0], [10.0, 10.0]]))
    np.testing.assert_allclose((g[1] - g[0]) / 4.0, [300.0, 80.0], atol=40.0)


@pytest.mark.slow
def test_process_noise_tracks_the_sinking_support_of_the_scour_bag(root: Path) -> None:
    import yaml

    from bridge_shadow.bagio import read_monitoring
    from bridge_shadow.model.surrogate_file import load_surrogate

    bag = root / "bags" / "scour_3d"
    truth = yaml.safe_load((bag / "truth.yaml").read_text())  # scoring only
    end_m = -truth["effects"]["settlement_drift"] * truth["days"]  # the south support sinks
    data = read_monitoring(bag)
    static = Shadow(ShadowConfig(), load_surrogate()).run(data)
    moving = Shadow(ShadowConfig(process_noise_m2_per_s=[1e-13, 1e-13]), load_surrogate()).run(data)
    assert not moving.events  # a drift that the random walk follows is not a step
    assert abs(moving.mean_m[0] - end_m) < 0.1e-3  # tracks the end value
    assert abs(moving.mean_m[1]) < 0.05e-3  # north stays put
    # Q = 0 averages over the data it has, and the drift it does not model is never silent: the
    # runs of windows that stay away from the estimate are reported (events or unconfirmed
    # changes), and the south support's reported changes add up to a sinking
    assert abs(static.mean_m[0] - end_m) > 0.15e-3
    js = static.to_json()
    reported = [*js["events"], *js["unconfirmed_changes"]]
    assert reported and sum(c["size_m"][0] for c in reported) < -0.15e-3


def test_nan_temperature_at_a_window_end_does_not_make_chunking_matter(root: Path) -> None:
    """A rejected (NaN) reading exactly at a window end must not close the window early.

    ``bags/baseline_1d`` has such a reading (1/60 Hz temperature, so the gap is 120 s, longer
    than the 30 s topic timeout): small chunks used to close that window before the next valid
    reading arrived and hold the temperature instead of interpolating it (1.6e-6 relative).
    """
    from bridge_shadow.bagio import read_monitoring
    from bridge_shadow.model.surrogate_file import load_surrogate

    data = read_monitoring(root / "bags" / "baseline_1d")
    t = data.temperature
    w_ns = 60 * 10**9
    assert np.any(~np.isfinite(t.temp_c) & (t.stamp_ns % w_ns == 0)), "the bag lost its edge case"
    cfg = load_config(overrides={"window_min_samples": 2})
    small = Shadow(cfg, load_surrogate()).run(data, chunk=7)
    big = Shadow(cfg, load_surrogate()).run(data)
    assert small.updates == big.updates > 1000
    np.testing.assert_allclose(small.mean_m, big.mean_m, rtol=1e-12, atol=0)
    np.testing.assert_allclose(small.covariance_m2, big.covariance_m2, rtol=1e-12, atol=0)


def test_diagnostics_warn_until_the_noise_model_has_seen_a_day() -> None:
    """Intervals from less than a day of residuals are flagged; after a whole day the level is OK."""
    short = Shadow(small_config(), placeholder_surrogate())
    short.run(synthetic(minutes=240, rate=1))
    diag = short.diagnostics()
    assert diag["windows"]["warm"] and diag["level"] == "WARN"
    assert "optimistic" in diag["message"] and "4.0 h" in diag["message"]
    day = Shadow(small_config(), placeholder_surrogate())
    day.run(synthetic(minutes=24 * 60 + 30, rate=1))
    assert day.diagnostics()["level"] == "OK"
    fixed = Shadow(small_config(noise_mode="fixed"), placeholder_surrogate())
    fixed.run(synthetic(minutes=240, rate=1))
    assert "optimistic" not in fixed.diagnostics()["message"]  # a fixed noise model does not learn


def test_systematic_term_widens_the_published_covariance_only(root: Path) -> None:
    """A^-1 diag(s^2) A^-T joins every published covariance; means and filter are untouched."""
    import yaml

    from bridge_shadow.bagio import read_monitoring
    from bridge_shadow.model.surrogate_file import load_surrogate

    bag = root / "bags" / "baseline_1d"
    truth = yaml.safe_load((bag / "truth.yaml").read_text())  # scoring only
    x_true = np.asarray(truth["settlement"]["mean_m"], float)
    data = read_monitoring(bag)
    sur = load_surrogate()
    paper = Shadow(ShadowConfig(), sur).run(data)
    wide = Shadow(ShadowConfig(systematic_sigma_n=[100.0, 100.0]), sur).run(data)
    a_inv = np.linalg.inv(sur.A)
    term = a_inv @ np.diag([1e4, 1e4]) @ a_inv.T
    np.testing.assert_allclose(wide.mean_m, paper.mean_m, rtol=1e-12, atol=0)  # means untouched
    np.testing.assert_allclose(wide.covariance_m2, paper.covariance_m2 + term, rtol=1e-12)
    np.testing.assert_allclose(
        wide.outputs[-1].covariance_m2, paper.outputs[-1].covariance_m2 + term, rtol=1e-12
    )
    err = paper.mean_m - x_true
    # the level is the record's mean (the paper's y - g(T) + ybar), as the twin's reference
    # temperature is: the paper's posterior covers the truth, the wider one does too
    assert err @ np.linalg.solve(paper.covariance_m2, err) <= 5.991
    assert err @ np.linalg.solve(wide.covariance_m2, err) <= 5.991
    with pytest.raises(ConfigError):
        ShadowConfig(systematic_sigma_n=[-1.0, 0.0])


def test_a_calibrated_surrogates_model_uncertainty_joins_the_published_covariance() -> None:
    """Surrogate.model_covariance(x) widens the interval where the calibration is uncertain."""
    from bridge_shadow.model.surrogate_file import Surrogate

    base = placeholder_surrogate()
    cov = np.diag([(0.05 * base.A[0, 0]) ** 2, 0.0, 0.0, (0.05 * base.A[1, 1]) ** 2, 500.0**2, 500.0**2])
    uncertain = Surrogate(base.A, base.u0, base.thermal, base.provenance, cov)
    data = synthetic(minutes=60, rate=2, x_m=(1e-3, -1e-3))
    plain = Shadow(small_config(), base).run(data)
    wide = Shadow(small_config(), uncertain).run(data)
    np.testing.assert_allclose(wide.mean_m, plain.mean_m, rtol=1e-12, atol=0)
    extra = uncertain.model_covariance(wide.mean_m)
    assert np.all(np.diag(extra) > 0)
    np.testing.assert_allclose(wide.covariance_m2, plain.covariance_m2 + extra, rtol=1e-12)
    np.testing.assert_allclose(
        wide.outputs[-1].covariance_m2, plain.outputs[-1].covariance_m2 + extra, rtol=1e-12
    )


@pytest.mark.parametrize(("outage_min", "kind"), [(5, "step"), (30, "gap")])
def test_gap_s_decides_whether_an_outage_is_a_gap(outage_min: int, kind: str) -> None:
    """``gap_s`` (600 s) decides: a step the detector finds, or a change at a gap.

    A change during a short outage is a step the detector finds at the first window after it;
    across a longer one it is a change at a gap, weighed by the next data.
    """
    data = synthetic(minutes=150, rate=2, seed=5)
    cut_lo, cut_hi = T0 + 80 * 60 * S, T0 + (80 + outage_min) * 60 * S
    forces = {}
    for c, ch in enumerate(CHANNELS):
        f = data.forces[ch]
        y = f.force_n + (f.stamp_ns >= cut_hi) * (placeholder_surrogate().A[c] @ np.array([-1e-3, -1e-3]))
        keep = (f.stamp_ns < cut_lo) | (f.stamp_ns >= cut_hi)
        forces[ch] = ForceSeries(f.stamp_ns[keep], y[keep], f.frame_id[keep])
    data = MonitoringData(forces, data.temperature)
    shadow = Shadow(small_config(), placeholder_surrogate())
    res = shadow.run(data)
    assert [(e.kind, e.window) for e in res.events] == [(kind, cut_hi // (60 * S))]
    assert len(shadow.gaps) == (kind == "gap")
    sd = np.sqrt(np.diag(res.events[0].covariance_m2))
    np.testing.assert_allclose(res.events[0].size_m, [-1e-3, -1e-3], atol=4 * sd.max())


def test_a_scheduled_refit_runs_after_the_window_output_and_before_the_next(monkeypatch) -> None:
    """A window that schedules a refit is output first; the refit runs at ``settle`` or the next window.

    The node calls ``settle`` in its idle time; every number is the same as without the pause.
    """
    data = synthetic(minutes=60, rate=2, seed=3)
    pauses: list[int] = []
    poll = Shadow.poll

    def poll_and_look(self: Shadow, now_ns=None):
        out = poll(self, now_ns)
        if self._pending_refit is not None:  # the state as published: the refit has not run yet
            fit_id = self._fit_id
            self.settle()
            assert self._fit_id > fit_id and self._pending_refit is None
            pauses.append(fit_id)
        return out

    # the traffic screen would hold this hour's first half and close it at once, not paced
    direct = Shadow(small_config(traffic_hold_s=0.0)).run(data, chunk=10**7)
    monkeypatch.setattr(Shadow, "poll", poll_and_look)
    paced = Shadow(small_config(traffic_hold_s=0.0)).run(data, chunk=40)  # about a window at a time
    assert len(pauses) >= 3
    np.testing.assert_allclose(paced.mean_m, direct.mean_m, rtol=1e-10, atol=1e-15)
    a, b = (np.array([o.mean_m for o in r.outputs]) for r in (direct, paced))
    np.testing.assert_allclose(b, a, rtol=1e-9, atol=1e-15)

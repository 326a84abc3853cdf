"""Calibration building blocks against closed forms: evidence, bounds, LM, SVD, car detection, changes."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import optimize, stats

from bridge_shadow.calibrate.car import bin_record, detect_car
from bridge_shadow.calibrate.change import measured_change, record_level
from bridge_shadow.calibrate.errors import CalibrationError
from bridge_shadow.calibrate.identifiability import identifiability
from bridge_shadow.calibrate.lm import levenberg_marquardt
from bridge_shadow.calibrate.posterior import laplace
from bridge_shadow.calibrate.spec import spec_from_dict
from bridge_shadow.series import MonitoringData

NS = 1_000_000_000


def _linear(y, g, sd):
    """Whitened residual function of y = G u + e, e ~ N(0, diag(sd^2)), prior u ~ N(0, I)."""

    def fun(u, jacobian=True):
        r = np.concatenate([(y - g @ u) / sd, u])
        return r, (np.vstack([-g / sd[:, None], np.eye(len(u))]) if jacobian else None)

    return fun


def test_laplace_evidence_is_exact_for_a_linear_gaussian_model() -> None:
    rng = np.random.default_rng(0)
    g = rng.normal(size=(2, 4)) * [[3.0], [0.5]]
    sd = np.array([0.3, 0.7])
    y = rng.normal(size=2) * 2
    fun = _linear(y, g, sd)
    res = levenberg_marquardt(fun, np.zeros(4))
    post = laplace(res.r, res.J, res.x, np.full(4, np.inf), 2, float(np.sum(np.log(sd**2))))
    exact = stats.multivariate_normal(np.zeros(2), np.diag(sd**2) + g @ g.T).logpdf(y)
    assert post.log_evidence == pytest.approx(exact, abs=1e-8)
    np.testing.assert_allclose(post.cov, np.linalg.inv(np.eye(4) + g.T @ np.diag(sd**-2) @ g), rtol=1e-8)


@pytest.mark.parametrize("y", [-2.0, 0.3, 2.5])
def test_bounded_evidence_and_interval_are_exact_for_a_half_normal_prior(y) -> None:
    """U <= 0 (a fraction at its as-built 1): evidence = N(y; 0, s^2 + g^2) 2 Phi(-m / sqrt(v))."""
    g, s = 1.5, 0.8
    fun = _linear(np.array([y]), np.array([[g]]), np.array([s]))
    res = levenberg_marquardt(fun, np.array([-0.5]), upper=np.array([0.0]))
    post = laplace(res.r, res.J, res.x, np.array([0.0]), 1, float(np.log(s**2)))
    v = 1.0 / (1.0 + g**2 / s**2)
    m = v * g * y / s**2
    exact = stats.norm(0, np.sqrt(s**2 + g**2)).logpdf(y) + np.log(2 * stats.norm.cdf(-m / np.sqrt(v)))
    assert post.log_evidence == pytest.approx(exact, abs=1e-8)
    truncated = stats.truncnorm(-np.inf, -m / np.sqrt(v), loc=m, scale=np.sqrt(v))
    lo, hi = post.lo95[0], post.hi95[0]
    assert truncated.cdf(hi) - truncated.cdf(lo) == pytest.approx(0.95, abs=1e-6)
    if hi < 0.0:  # highest density: equal density at both ends, else the interval reaches the bound
        assert truncated.pdf(lo) == pytest.approx(truncated.pdf(hi), rel=1e-5)
    assert lo <= min(res.x[0], 0.0) and hi >= res.x[0]
    assert bool(post.active[0]) == (m > 0)  # the mode sits on the bound when the data push past it
    assert res.x[0] <= 0.0


def test_lm_matches_scipy_least_squares_on_a_nonlinear_problem() -> None:
    t = np.linspace(0, 3, 12)
    y = 2.0 * np.exp(-1.3 * t) + 0.05 * np.sin(7 * t)

    def resid(p):
        return y - p[0] * np.exp(-p[1] * t)

    def fun(p, jacobian=True):
        e = np.exp(-p[1] * t)
        return resid(p), (np.column_stack([-e, p[0] * t * e]) if jacobian else None)

    ours = levenberg_marquardt(fun, np.array([1.0, 0.5]))
    ref = optimize.least_squares(resid, [1.0, 0.5], xtol=1e-14, ftol=1e-14, gtol=1e-14)
    np.testing.assert_allclose(ours.x, ref.x, rtol=1e-5)
    assert ours.converged


def test_identifiability_finds_the_combination_the_data_fix() -> None:
    j = np.array([[10.0, 10.0, 0.0], [0.0, 0.0, 0.01]])  # one number sees a + b, the other almost nothing
    rep = identifiability(j, ["a", "b", "c"])
    first = rep["directions"][0]
    assert first["singular_value"] == pytest.approx(np.sqrt(200.0))
    assert first["combination"] == {"a": pytest.approx(0.707, abs=1e-3), "b": pytest.approx(0.707, abs=1e-3)}
    assert rep["directions"][1]["posterior_to_prior_sd"] == pytest.approx(1.0, abs=1e-4)
    assert "2 measured numbers" in rep["summary"]


def _record(start_ns, level, rate, steps=(), seconds=720, hz=20, seed=0, temp=2.0):
    """Synthetic load-cell record: level + drift + car events (t0, t1, height per channel) + noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * hz)) / hz
    y = np.asarray(level, float)[None, :] + np.outer(t, rate)
    for t0, t1, h in steps:
        y[(t >= t0) & (t < t1)] += h
    y += rng.normal(0, 20.0, y.shape)
    stamps = start_ns + np.round(t * NS).astype(np.int64)
    tt = start_ns + np.arange(0, seconds, 1.0).astype(np.int64) * NS
    return MonitoringData.from_arrays(stamps, y, tt, np.full(len(tt), temp))


CAR = [
    (20, 35, [4000.0, 3000.0]),
    (120, 240, [5600.0, 4600.0]),
    (250, 370, [10400.0, 9900.0]),
    (400, 415, [5000.0, 2000.0]),
]


def test_car_detection_finds_crossings_plateaus_and_the_baseline() -> None:
    data = _record(0, [234e3, 233e3], [1.0, 0.0], CAR)
    det = detect_car(bin_record(data))
    assert len(det.plateaus) == 2
    np.testing.assert_allclose(det.plateaus[0].height_n, [5600, 4600], atol=60)
    np.testing.assert_allclose(det.plateaus[1].height_n, [10400, 9900], atol=60)
    np.testing.assert_allclose(det.baseline[:, 1], [1.0, 0.0], atol=0.05)  # drift N/s
    assert len(det.intervals_s) == 3  # two crossings and the parked sequence
    assert 0.3 < det.free_fraction < 0.55


def test_measured_change_linear_recovers_a_step_under_drift_and_uncertainty_covers_it() -> None:
    """Both records drift +1 N/s; the step between them is -20 / -40 kN."""
    step = np.array([-20e3, -40e3])
    t_b, t_a = 0, 2640 * NS  # 44 min apart
    before = record_level(_record(t_b, [234e3, 234e3], [1.0, 1.0], CAR, seed=1))
    level_a = np.array([234e3, 234e3]) + step + 2640.0 * 1.0
    after = record_level(_record(t_a, level_a, [1.0, 1.0], CAR, seed=2))
    lin = measured_change(before, after, "linear")
    np.testing.assert_allclose(lin.dR_n, step, atol=60)  # the drift over the gap is modelled away
    unc = measured_change(before, after, "uncertainty")
    z = (unc.dR_n - step) / unc.sd_n
    assert np.all(np.abs(z) < 2.0) and np.all(unc.sd_n > 2000.0)  # unmodelled: 2.6 kN of drift is in the sd
    assert unc.air_temp_change_k == pytest.approx(0.0)


def test_spec_errors_are_one_line() -> None:
    good = {
        "pairs": [
            {
                "name": "p",
                "before": "a",
                "after": "b",
                "imposed_m": [-0.01, -0.01],
                "imposed_sd_m": [5e-4, 5e-4],
            }
        ]
    }
    assert spec_from_dict(good).pairs[0].imposed_m.tolist() == [-0.01, -0.01]  # exact: passed through
    bad = [
        {"pairs": []},
        {"pairs": [{**good["pairs"][0], "imposed_sd_m": [0, 1e-3]}]},
        {**good, "explanations": {"x": ["no_such_parameter"]}},
        {**good, "choose": "nothing"},
        {**good, "mesh": "huge"},
    ]
    for data in bad:
        with pytest.raises(CalibrationError) as err:
            spec_from_dict(data)
        assert "\n" not in str(err.value)


def test_a_pair_listed_twice_or_of_one_record_is_refused() -> None:
    """Two names for one pair counted its records as independent data twice, without a word.

    (The public pair listed twice moved the explanations' weights from 0.83 / 0.17 to 0.58 /
    0.42.) A pair whose 'before' and 'after' are one record was refused as if they were swapped.
    """
    pair = {
        "name": "p",
        "before": ["a.zip", "t.zip"],
        "after": ["b.zip", "t.zip"],
        "imposed_m": [-0.01, -0.01],
        "imposed_sd_m": [5e-4, 5e-4],
    }
    again = {**pair, "name": "q", "before": ["./a.zip", "t.zip"]}
    with pytest.raises(CalibrationError, match="pairs p and q read the same records"):
        spec_from_dict({"pairs": [pair, again]})
    with pytest.raises(CalibrationError, match="pair s: its 'before' and 'after' are the same record"):
        spec_from_dict({"pairs": [{**pair, "name": "s", "after": pair["before"]}]})
    other = {**pair, "name": "r", "after": ["c.zip", "t.zip"]}  # same before, another after: fine
    assert [p.name for p in spec_from_dict({"pairs": [pair, other]}).pairs] == ["p", "r"]


@pytest.mark.parametrize("y", [-9.0, -1.0, 0.4, 6.0])
def test_evidence_and_interval_are_exact_for_a_prior_truncated_on_both_sides(y) -> None:
    """-3.29 <= u <= 3.29 (a plausible range): evidence = N(y; 0, s^2 + g^2) P(box | y) / P(box)."""
    a, b = -3.2905267314919255, 3.2905267314919255
    g, s = 2.0, 0.5
    fun = _linear(np.array([y]), np.array([[g]]), np.array([s]))
    res = levenberg_marquardt(fun, np.zeros(1), lower=np.array([a]), upper=np.array([b]))
    post = laplace(res.r, res.J, res.x, np.array([b]), 1, float(np.log(s**2)), lower=np.array([a]))
    v = 1.0 / (1.0 + g**2 / s**2)
    m = v * g * y / s**2
    box = stats.norm.cdf(b) - stats.norm.cdf(a)
    given_y = stats.norm.cdf(b, m, np.sqrt(v)) - stats.norm.cdf(a, m, np.sqrt(v))
    exact = stats.norm(0, np.sqrt(s**2 + g**2)).logpdf(y) + np.log(given_y / box)
    assert post.log_evidence == pytest.approx(exact, abs=1e-8)
    assert a <= res.x[0] <= b and (post.active[0] == (abs(m) > b))
    truncated = stats.truncnorm((a - m) / np.sqrt(v), (b - m) / np.sqrt(v), loc=m, scale=np.sqrt(v))
    assert truncated.cdf(post.hi95[0]) - truncated.cdf(post.lo95[0]) == pytest.approx(0.95, abs=1e-6)
    assert post.mean[0] == pytest.approx(truncated.mean(), abs=1e-7)  # the mode to the LM tolerance


def test_truncated_moments_far_beyond_a_bound_are_the_exponential_limit() -> None:
    """The truncated-normal moments of scipy 1080 sds beyond a bound came out NaN, with warnings.

    Where scipy's are finite they are used as they are (exactly its values); far in a tail the
    exponential limit (rate z / scale at the near bound) stands in, which scipy's own values
    approach (within 0.2 % at 40 sds).
    """
    import warnings

    from scipy import stats

    from bridge_shadow.calibrate.posterior import _truncated_moments

    for centre, lower, upper in ((0.0, -1.0, 2.0), (-3.0, 1.0, np.inf), (5.0, -np.inf, 1.0)):
        a, b = lower - centre, upper - centre
        dist = stats.truncnorm(a, b, loc=centre, scale=1.0)
        got = _truncated_moments(dist, a, b, lower, upper, 1.0)
        np.testing.assert_allclose(got, (dist.mean(), dist.std(), dist.median()), rtol=1e-12)
    far = stats.truncnorm(40.0, np.inf, loc=-40.0, scale=1.0)
    limit_sd = 1.0 / 40.0
    np.testing.assert_allclose(far.std(), limit_sd, rtol=2e-3)
    np.testing.assert_allclose(far.mean(), limit_sd, rtol=2e-3)
    sd0 = 0.095
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for alpha, beta, lower, upper, sign in (
            (1080.4, 1149.7, -3.29, -3.29 + 69.3 * sd0, 1.0),
            (-1149.7, -1080.4, 3.29 - 69.3 * sd0, 3.29, -1.0),
        ):
            centre = lower - alpha * sd0 if sign > 0 else upper - beta * sd0
            dist = stats.truncnorm(alpha, beta, loc=centre, scale=sd0)
            mean, sd, median = _truncated_moments(dist, alpha, beta, lower, upper, sd0)
            edge = lower if sign > 0 else upper
            np.testing.assert_allclose(sd, sd0 / 1080.4, rtol=1e-6)
            np.testing.assert_allclose(
                [mean, median], [edge + sign * sd, edge + sign * sd * np.log(2.0)], rtol=1e-9
            )


def test_the_calibration_file_is_named_as_the_checkout_holds_it(tmp_path) -> None:
    """Provenance names a checkout's own file relative to it (it named a scratch clone's path)."""
    from bridge_shadow.calibrate.run import _shown_path
    from bridge_shadow.paths import repo_root

    root = repo_root()
    assert root is not None
    assert _shown_path(root / "config" / "calibration.yaml") == "config/calibration.yaml"
    outside = tmp_path / "calibration.yaml"
    assert _shown_path(outside) == str(outside.resolve())

"""Kalman update: filterpy 2.0.0 shape bug and our immunity, batch posterior, Joseph form, NaN gate."""

from __future__ import annotations

import filterpy
import numpy as np
import pytest
from filterpy.kalman import KalmanFilter

from bridge_shadow.estimate import Shadow, ShadowConfig
from bridge_shadow.estimate.settlement.kalman import SettlementFilter, batch_posterior
from bridge_shadow.model.surrogate_file import placeholder_surrogate
from bridge_shadow.series import MonitoringData

SIGMA_X = np.diag([3e-4, 3e-4]) ** 2
SIGMA_E = np.diag([60.4, 82.7]) ** 2


def _samples(m: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    sur = placeholder_surrogate()
    rng = np.random.default_rng(seed)
    x_true = np.array([7e-4, -7e-4])
    y = sur.reactions(x_true) + rng.normal(0.0, 1.0, (m, 2)) * np.sqrt(np.diag(SIGMA_E))
    return y, x_true


def test_filterpy_200_shape_bug_and_wrapper_immunity() -> None:
    assert filterpy.__version__ == "2.0.0"
    A = placeholder_surrogate().A
    z = np.array([500.0, -300.0])
    kf = KalmanFilter(dim_x=2, dim_z=2)
    kf.x, kf.P = np.zeros((2, 1)), SIGMA_X.copy()
    kf.update(z, R=SIGMA_E, H=A)  # 1-D z with H given: filterpy skips reshape_z
    assert kf.x.shape == (2, 2)  # silently broadcast: the state is no longer a vector
    ours = SettlementFilter(A, np.sqrt(np.diag(SIGMA_X)))
    res = ours.update(z, SIGMA_E)
    assert res.accepted and ours.x.shape == (2,) and ours.kf.x.shape == (2, 1)
    ref_mean, ref_cov = batch_posterior(A, SIGMA_X, SIGMA_E, z[None, :])
    assert np.allclose(ours.x, ref_mean, rtol=1e-10, atol=0.0)
    assert np.allclose(ours.P, ref_cov, rtol=1e-10, atol=0.0)


def test_per_sample_updates_equal_the_batch_formula() -> None:
    sur = placeholder_surrogate()
    y, _ = _samples(500)
    f = SettlementFilter(sur.A, np.sqrt(np.diag(SIGMA_X)))
    for yi in y:
        assert f.update(yi - sur.u0, SIGMA_E, gate=False).accepted
    mean, cov = batch_posterior(sur.A, SIGMA_X, SIGMA_E, y - sur.u0)
    assert np.allclose(f.x, mean, rtol=1e-10, atol=1e-20)
    assert np.allclose(f.P, cov, rtol=1e-10, atol=0.0)
    assert np.array_equal(f.P, f.P.T)  # Joseph form, then symmetrized
    assert np.all(np.linalg.eigvalsh(f.P) > 0)


def test_shadow_windows_with_q0_equal_the_batch_formula() -> None:
    # Window means with R = Sigma_E / m_w carry exactly the information of their samples, so the
    # pipeline (no compensation, fixed noise) reproduces the paper's batch posterior.
    sur = placeholder_surrogate()
    rate, seconds = 20, 1800
    y, _ = _samples(rate * seconds, seed=4)
    t0 = 1_650_000_000 * 10**9 + 123_456_789
    stamps = t0 + np.arange(len(y)) * (10**9 // rate)
    temp_stamps = t0 + np.arange(seconds + 1) * 10**9
    data = MonitoringData.from_arrays(stamps, y, temp_stamps, np.full(seconds + 1, 8.0))
    config = ShadowConfig(
        smoothing="none",
        noise_mode="fixed",
        prior_sigma_m=[3e-4, 3e-4],
        warmup_windows=1,
        window_min_samples=1,
        event_detection=False,
        mahalanobis_probability=1.0,
    )
    result = Shadow(config, sur).run(data)
    mean, cov = batch_posterior(sur.A, SIGMA_X, SIGMA_E, y - sur.u0)
    assert result.updates == 31  # partial first and last windows included
    assert np.allclose(result.mean_m, mean, rtol=1e-10, atol=1e-20)
    assert np.allclose(result.covariance_m2, cov, rtol=1e-10, atol=0.0)


def test_nonfinite_and_outlier_measurements_are_gated() -> None:
    sur = placeholder_surrogate()
    f = SettlementFilter(sur.A, np.array([3e-4, 3e-4]), gate_probability=0.999)
    before = f.x, f.P
    assert f.update(np.array([np.nan, 1.0]), SIGMA_E).reason == "nonfinite"
    assert f.update(np.array([1.0, np.inf]), SIGMA_E).reason == "nonfinite"
    assert f.update(np.array([1e6, -1e6]), SIGMA_E).reason == "outlier"
    assert np.array_equal(f.x, before[0]) and np.array_equal(f.P, before[1])  # exact: untouched copies
    assert f.update(np.array([100.0, -50.0]), SIGMA_E).accepted


def test_process_noise_tracks_a_moving_settlement() -> None:
    sur = placeholder_surrogate()
    rng = np.random.default_rng(9)
    q = 1e-12  # m^2 per s
    f_static = SettlementFilter(sur.A, np.array([3e-4, 3e-4]))
    f_track = SettlementFilter(sur.A, np.array([3e-4, 3e-4]), q_rate=np.array([q, q]))
    R = SIGMA_E / 6000
    for k in range(600):
        x = np.array([1e-6 * k, 0.0])  # 1 um per minute, 0.6 mm after 10 h
        z = sur.A @ x + rng.normal(0.0, 1.0, 2) * np.sqrt(np.diag(R))
        f_static.update(z, R, gate=False)
        f_track.predict(60.0)
        f_track.update(z, R, gate=False)
    assert abs(f_track.x[0] - 599e-6) < 20e-6
    assert abs(f_static.x[0] - 599e-6) > 200e-6
    with pytest.raises(AssertionError):
        np.testing.assert_allclose(f_track.P, f_static.P)

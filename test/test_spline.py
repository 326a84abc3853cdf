"""Online P-spline: batch equality, scipy's smoothing spline, exact penalty, REML/GCV, edf."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import make_smoothing_spline

from bridge_shadow.estimate.compensation.spline import (
    OnlinePSpline,
    basis_nonzero,
    clamped_knots,
    gram_penalty,
)


def _data(n: int = 300, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = rng.uniform(-5.0, 25.0, n)
    y = 230e3 + 400.0 * t + 2e3 * np.sin(t / 3.0) + rng.normal(0.0, 300.0, n)
    return t, y


def _batch(sp: OnlinePSpline, t: np.ndarray, y: np.ndarray, w: np.ndarray, lam: float) -> np.ndarray:
    """Direct penalized least squares on the full design matrix."""
    b = sp.basis(t)
    return np.linalg.solve(b.T @ (w[:, None] * b) + lam * sp.omega, b.T @ (w * y))


def test_online_equals_batch_fit_any_chunking() -> None:
    t, y = _data()
    for lam in (1e-2, 10.0, 1e4):
        online = OnlinePSpline.uniform(-10.0, 30.0, 12, mode="fixed", lam=lam)
        for part in np.array_split(np.arange(len(t)), 17):
            online.add(t[part], y[part])
        beta = _batch(online, t, y, np.ones_like(t), lam)
        assert np.allclose(online.fit().beta, beta, rtol=1e-8, atol=0.0)
        assert online.fit().mean_y == pytest.approx(np.mean(y), rel=1e-12)


def test_forgetting_is_a_weighted_batch_fit() -> None:
    t, y = _data(120, seed=3)
    rho = 0.97
    online = OnlinePSpline.uniform(-10.0, 30.0, 10, mode="fixed", lam=5.0)
    for i in range(len(t)):
        online.add(t[i], y[i], decay=rho if i else 1.0)
    w = rho ** np.arange(len(t) - 1, -1, -1.0)
    beta = _batch(online, t, y, w, 5.0)
    assert np.allclose(online.fit().beta, beta, rtol=1e-8, atol=0.0)
    assert online.fit().mean_y == pytest.approx(np.sum(w * y) / np.sum(w), rel=1e-12)


@pytest.mark.parametrize("lam", [1e-3, 0.5, 10.0, 300.0])
def test_equals_make_smoothing_spline_with_knots_at_the_data(lam: float) -> None:
    # With knots at the (distinct) data points and the range [x_0, x_n], the penalized cubic
    # spline is the natural smoothing spline, the minimizer scipy computes for the same lambda.
    rng = np.random.default_rng(7)
    x = np.sort(rng.uniform(0.0, 20.0, 50))
    y = np.cos(x / 2.0) + rng.normal(0.0, 0.1, len(x))
    ref = make_smoothing_spline(x, y, lam=lam)
    online = OnlinePSpline(x, mode="fixed", lam=lam)
    for part in np.array_split(rng.permutation(len(x)), 5):
        online.add(x[part], y[part])
    grid = np.linspace(x[0], x[-1], 301)
    assert np.allclose(online.predict(grid), ref(grid), rtol=0.0, atol=1e-8 * np.ptp(y))


def test_penalty_is_exact_for_a_quadratic() -> None:
    # g(T) = T^2 lies in the cubic spline space; int g''^2 over [a, b] = 4 (b - a).
    knots = clamped_knots(np.array([-3.0, -1.0, 0.5, 2.0, 6.0]))
    omega = gram_penalty(knots)
    grid = np.linspace(-3.0, 6.0, 40)
    sp = OnlinePSpline(np.array([-3.0, -1.0, 0.5, 2.0, 6.0]), mode="fixed", lam=0.0)
    beta = np.linalg.lstsq(sp.basis(grid), grid**2, rcond=None)[0]
    assert beta @ omega @ beta == pytest.approx(4.0 * 9.0, rel=1e-12)
    # and linear functions are not penalized (null space of dimension 2)
    assert np.sum(np.linalg.eigvalsh(omega) < 1e-10 * np.linalg.eigvalsh(omega).max()) == 2


def _dense_scores(
    sp: OnlinePSpline, t: np.ndarray, y: np.ndarray, log_lams: np.ndarray
) -> dict[str, np.ndarray]:
    """REML and GCV computed the textbook way from the full design matrix."""
    b = sp.basis(t)
    n = len(y)
    eig = np.linalg.eigvalsh(sp.omega)
    pos = eig[eig > 1e-9 * eig.max()]
    reml, gcv = [], []
    for ll in log_lams:
        lam = 10.0**ll
        lhs = b.T @ b + lam * sp.omega
        beta = np.linalg.solve(lhs, b.T @ y)
        rss = np.sum((y - b @ beta) ** 2)
        pen = lam * beta @ sp.omega @ beta
        edf = np.trace(np.linalg.solve(lhs, b.T @ b))
        reml.append((n - 2) * np.log(rss + pen) + np.linalg.slogdet(lhs)[1] - np.sum(np.log(lam * pos)))
        gcv.append(n * rss / (n - edf) ** 2)
    return {"reml": np.array(reml), "gcv": np.array(gcv)}


@pytest.mark.parametrize("mode", ["reml", "gcv"])
def test_lambda_selection_matches_dense_criterion(mode: str) -> None:
    t, y = _data(400, seed=11)
    sp = OnlinePSpline.uniform(-10.0, 30.0, 12, mode=mode)
    sp.add(t, y)
    lam = sp.fit().lam
    grid = np.log10(lam) + np.linspace(-1.5, 1.5, 61)
    scores = _dense_scores(sp, t, y, grid)[mode]
    # the selected lambda minimizes the textbook criterion (to the grid resolution)
    assert abs(grid[np.argmin(scores)] - np.log10(lam)) <= 0.05 + 1e-9
    assert 2.0 < sp.fit().edf < 15.0


def test_edf_is_trace_of_hat_matrix_and_clamping_is_counted() -> None:
    t, y = _data(200, seed=5)
    sp = OnlinePSpline.uniform(0.0, 20.0, 8, mode="fixed", lam=50.0)
    sp.add(t, y)
    b = sp.basis(t)
    hat = b @ np.linalg.solve(b.T @ b + 50.0 * sp.omega, b.T)
    assert sp.fit().edf == pytest.approx(np.trace(hat), rel=1e-10)
    assert sp.n_clamped == int(np.sum((t < 0.0) | (t > 20.0)))
    assert sp.predict(np.array([-40.0]))[0] == pytest.approx(sp.predict(np.array([0.0]))[0], rel=1e-14)


def test_state_round_trip_gives_the_same_fit() -> None:
    t, y = _data(100, seed=2)
    a = OnlinePSpline.uniform(-10.0, 30.0, 12)
    a.add(t, y)
    b = OnlinePSpline.uniform(-10.0, 30.0, 12)
    b.load_state_dict(a.state_dict())
    np.testing.assert_allclose(a.fit().beta, b.fit().beta, rtol=1e-12, atol=0)
    assert a.fit().lam == pytest.approx(b.fit().lam, rel=1e-12)


def test_basis_equals_scipy_design_matrix() -> None:
    from scipy.interpolate import BSpline

    bp = np.array([-20.0, -7.0, -1.0, 0.0, 4.5, 12.0, 30.0, 45.0])
    sp = OnlinePSpline(bp)
    x = np.concatenate([np.linspace(-20.0, 45.0, 501), bp])
    ref = BSpline.design_matrix(x, sp.knots, 3).toarray()
    assert np.allclose(sp.basis(x), ref, rtol=0.0, atol=1e-14)
    assert np.allclose(sp.basis(x).sum(axis=1), 1.0, rtol=0.0, atol=1e-14)


def test_leverage_gives_leave_one_out_residuals() -> None:
    t, y = _data(60, seed=8)
    sp = OnlinePSpline.uniform(-10.0, 30.0, 8, mode="fixed", lam=20.0)
    sp.add(t, y)
    loo = (y[7] - sp.predict(t[7])[0]) / (1.0 - sp.leverage(t[7])[0])
    drop = OnlinePSpline.uniform(-10.0, 30.0, 8, mode="fixed", lam=20.0)
    drop.add(np.delete(t, 7), np.delete(y, 7))
    assert loo == pytest.approx(y[7] - drop.predict(t[7])[0], rel=1e-9)


def test_few_point_basis_equals_vectorized_basis() -> None:
    """The plain-float path for a handful of points is the same recursion as the vectorized one."""
    from bridge_shadow.estimate.compensation.spline import _SCALAR_PATH_MAX, _basis

    sp = OnlinePSpline(np.array([-20.0, -7.0, -1.0, 0.0, 4.5, 12.0, 30.0, 45.0]))
    x = np.concatenate([np.linspace(-20.0, 45.0, 97), [-7.0, 45.0, 30.0 - 1e-12]])
    many = _basis(sp.knots, x)
    assert len(x) > _SCALAR_PATH_MAX
    step = _SCALAR_PATH_MAX
    few = np.vstack([_basis(sp.knots, x[i : i + step]) for i in range(0, len(x), step)])
    np.testing.assert_allclose(few, many, rtol=0.0, atol=1e-15)
    # the non-zero part alone (what a closing window's compensation reads), both ways
    first, values = basis_nonzero(sp.knots, x)
    parts = [basis_nonzero(sp.knots, x[i : i + step]) for i in range(0, len(x), step)]
    np.testing.assert_array_equal(np.concatenate([p[0] for p in parts]), first)  # integer indices
    np.testing.assert_allclose(np.vstack([p[1] for p in parts]), values, rtol=0.0, atol=1e-15)
    rows = np.arange(len(x))[:, None]
    np.testing.assert_allclose(many[rows, first[:, None] + np.arange(4)], values, rtol=0.0, atol=1e-15)
    # clamping on the few-point path: outside the range equals the end values
    np.testing.assert_allclose(sp.basis([-50.0, 99.0]), sp.basis([-20.0, 45.0]), rtol=1e-12, atol=1e-15)

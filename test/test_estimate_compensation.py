"""Compensation fitted jointly with the segment levels.

It equals the dense penalized least squares, keeps a step in the levels, and follows the FE slope
where the data say nothing.
"""

from __future__ import annotations

import numpy as np

from bridge_shadow.estimate.compensation.fit import Compensation
from bridge_shadow.estimate.compensation.spline import _basis
from bridge_shadow.estimate.compensation.sums import FitSums, WindowRows


def _fit_rows(comp: Compensation, k, m, y, t, seg) -> FitSums:
    i0, bv = comp.basis_rows(t)
    sums = FitSums(comp.q)
    sums.add(WindowRows(np.asarray(k, np.int64), m, y, t, i0, bv, np.asarray(seg, np.int64)))
    return sums


def test_joint_fit_equals_the_dense_penalized_least_squares_with_levels() -> None:
    rng = np.random.default_rng(4)
    n = 400
    comp = Compensation(-20.0, 45.0, 13, slope_fe=np.array([19.0, -5.0]), slope_sd=300.0)
    t = np.column_stack([np.linspace(0, 15, n), np.linspace(2, 14, n)]) + rng.normal(0, 0.5, (n, 2))
    seg = (np.arange(n) >= 150).astype(int) + (np.arange(n) >= 300).astype(int)
    m = rng.integers(50, 61, (n, 2)).astype(float)
    y = 400.0 * np.sin(t / 4.0) + np.array([0.0, -3000.0, 2000.0])[seg][:, None] + rng.normal(0, 80, (n, 2))
    sums = _fit_rows(comp, np.arange(n), m, y, t, seg)
    lam, kappa = np.array([30.0, 5.0]), np.array([2.0, 0.5])
    fit = comp.fit(sums, lam, kappa)
    for c in range(2):
        B = _basis(comp.knots, t[:, c])
        X = np.column_stack([(seg == s).astype(float) for s in range(3)] + [B])
        H = X.T @ (m[:, c, None] * X)
        H[3:, 3:] += lam[c] * comp.omega + kappa[c] * comp.omega1
        rhs = X.T @ (m[:, c] * y[:, c])
        rhs[3:] += kappa[c] * comp.slope_fe[c] * comp.e
        con = np.concatenate([np.zeros(3), B.T @ m[:, c]])  # centred curve: sum m g(T) = 0
        kkt = np.block([[H, con[:, None]], [con[None, :], np.zeros((1, 1))]])
        sol = np.linalg.solve(kkt, np.concatenate([rhs, [0.0]]))
        np.testing.assert_allclose(fit.level[:, c], sol[:3], rtol=1e-8, atol=1e-6)
        np.testing.assert_allclose(fit.beta[c], sol[3:-1], rtol=1e-7, atol=1e-4)
        assert abs(m[:, c] @ (B @ fit.beta[c])) < 1e-6 * m[:, c].sum()


def test_a_step_during_a_temperature_rise_stays_in_the_levels() -> None:
    """Noise-free: forces follow 300 N/K and drop 5 kN while the air warms from 2 to 13 C."""
    n = 240
    t = np.column_stack([np.linspace(2.0, 13.0, n)] * 2)
    step = np.where(np.arange(n) >= 120, -5000.0, 0.0)
    y = 300.0 * (t - 7.0) + step[:, None]
    m = np.full((n, 2), 60.0)
    comp = Compensation(-20.0, 45.0, 13, slope_fe=np.array([19.0, 19.0]))
    joint = comp.fit(_fit_rows(comp, np.arange(n), m, y, t, np.arange(n) >= 120), np.array([1.0, 1.0]))
    np.testing.assert_allclose(joint.level[1] - joint.level[0], [-5000.0, -5000.0], rtol=1e-6)
    # the same curve fitted on the raw forces (one level, as a plain P-spline on y) takes a share of the
    # step as a temperature effect: the compensated drop is smaller
    alone = comp.fit(_fit_rows(comp, np.arange(n), m, y, t, np.zeros(n)), np.array([1.0, 1.0]))
    comp_y = y - comp.curve(alone, t)
    drop = comp_y[120:].mean(axis=0) - comp_y[:120].mean(axis=0)
    assert np.all(np.abs(drop) < 0.5 * 5000.0), drop


def test_beyond_the_seen_range_the_curve_follows_the_fe_slope() -> None:
    rng = np.random.default_rng(2)
    n = 30
    t = np.column_stack([np.linspace(1.6, 2.0, n)] * 2)  # a narrow range: a 12-minute record
    y = rng.normal(0, 3000.0, (n, 2))  # wild scatter (a test car) that a free trend would follow
    comp = Compensation(-20.0, 45.0, 13, slope_fe=np.array([19.0, 19.0]), slope_sd=500.0)
    sums = _fit_rows(comp, np.arange(n), np.full((n, 2), 6000.0), y, t, np.zeros(n))
    fit = comp.fit(sums, None, comp.slope_weight(np.full(2, 3000.0**2 * 6000.0)))
    g = comp.curve(fit, np.array([[2.0, 2.0], [5.0, 5.0], [-3.0, -3.0]]))
    # the scatter would make up a trend of several kN/K; the curve keeps near the FE slope instead
    np.testing.assert_allclose(g[1] - g[0], 3.0 * 19.0, rtol=0.15)
    np.testing.assert_allclose(g[0] - g[2], 5.0 * 19.0, rtol=0.15)
    var = comp.curve_variance(fit, *comp.basis_rows(np.array([[2.0, 2.0], [8.0, 8.0]])))
    assert np.all(var[1] > 4 * var[0])  # and knows it is less sure away from the data

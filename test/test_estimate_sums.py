"""Sufficient statistics.

Added in any batches they equal direct sums; residual moments from them equal a
direct pass over the residuals.
"""

from __future__ import annotations

import numpy as np

from bridge_shadow.estimate.compensation.fit import Compensation
from bridge_shadow.estimate.compensation.sums import FitSums, WindowRows, residual_moments


def rows(n: int = 300, seed: int = 0, n_seg: int = 3) -> WindowRows:
    rng = np.random.default_rng(seed)
    comp = Compensation(-20.0, 45.0, 13)
    k = np.cumsum(rng.choice([1, 1, 1, 2], n)).astype(np.int64)  # a few gaps
    t = 5.0 + 8.0 * np.sin(k / 50.0)[:, None] + rng.normal(0, 0.3, (n, 2))
    t[7, 1] = np.nan  # one window without temperature on one channel
    i0, bv = comp.basis_rows(t)
    m = rng.integers(40, 61, (n, 2)).astype(float)
    y = rng.normal(0.0, 300.0, (n, 2)) + 50.0 * t.clip(-50, 50)
    y[np.isnan(y)] = 0.0
    seg = np.minimum(np.arange(n) * n_seg // n, n_seg - 1)
    return WindowRows(k, m, y, t, i0, bv, seg)


def test_sums_in_batches_equal_direct_sums_and_residual_moments() -> None:
    r = rows()
    q = 16
    whole, parts = FitSums(q), FitSums(q)
    whole.add(r)
    for sl in np.array_split(np.arange(len(r.k)), 7):
        parts.add(WindowRows(*(getattr(r, f)[sl] for f in ("k", "m", "y", "t", "i0", "bv", "seg"))))
    b = r.dense_b(q)  # (n, 2, q)
    for name in ("G", "r", "sb", "LBB", "XBB", "sbs", "Lbcs"):
        np.testing.assert_allclose(getattr(parts, name), getattr(whole, name), rtol=1e-12, atol=1e-6)
    np.testing.assert_allclose(whole.G[0], (b[:, 0].T * r.m[:, 0]) @ b[:, 0], rtol=1e-12)
    np.testing.assert_allclose(whole.r[1], b[:, 1].T @ (r.m[:, 1] * r.y[:, 1]), rtol=1e-12)
    # residual moments of e = y - l_s - b'beta for arbitrary beta and levels, against a direct pass
    rng = np.random.default_rng(1)
    beta = rng.normal(0, 100, (2, q))
    level = rng.normal(0, 200, (3, 2))
    e = r.y - level[r.seg] - np.einsum("ncq,cq->nc", b, beta)
    u = np.sqrt(r.m) * e
    mom = residual_moments(whole, beta, level)
    np.testing.assert_allclose(np.diag(mom.s2), (u * u).sum(axis=0), rtol=1e-9)
    np.testing.assert_allclose(mom.s2[0, 1], (u[:, 0] * u[:, 1]).sum(), rtol=1e-9)
    pair = (np.diff(r.k) == 1) & (np.diff(r.seg) == 0)  # adjacent windows of one segment
    np.testing.assert_allclose(mom.lag, (u[:-1][pair] * u[1:][pair]).sum(axis=0), rtol=1e-9)
    assert mom.n_pairs == pair.sum() and mom.n == len(r.k)
    assert whole.t_lo[1] == np.nanmin(r.t[:, 1]) and whole.t_hi[0] == r.t[:, 0].max()

"""Settlement over segments.

One segment is the paper's closed form; the online update equals the exact
refresh; two segments with a jump equal the dense joint Gaussian; the float helpers equal numpy.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from bridge_shadow.estimate.compensation.fit import Compensation
from bridge_shadow.estimate.compensation.noise import NoiseModel
from bridge_shadow.estimate.compensation.sums import FitSums, Moments, WindowRows
from bridge_shadow.estimate.settlement.segments import SegmentChain, SegmentData
from bridge_shadow.estimate.small import congruence, inv_sym, mat_vec, quad_inv, sym_vec
from bridge_shadow.model.surrogate_file import placeholder_surrogate

SUR = placeholder_surrogate()
PRIOR = np.diag([4e-3, 4e-3]) ** 2


def _setup(n: int, seg: np.ndarray, seed: int = 0):
    rng = np.random.default_rng(seed)
    x = np.array([[0.3e-3, -0.2e-3], [-0.9e-3, -1.1e-3]])[seg]
    m = rng.integers(30, 61, (n, 2)).astype(float)
    y = x @ SUR.A.T + rng.normal(0, 400.0, (n, 2)) / np.sqrt(m)
    t = np.full((n, 2), np.nan)  # uncompensated: the curve drops out
    comp = Compensation(-20.0, 45.0, 13)
    i0, bv = comp.basis_rows(t)
    rows = WindowRows(np.arange(n, dtype=np.int64), m, y, t, i0, bv, seg.astype(np.int64))
    sums = FitSums(comp.q)
    sums.add(rows)
    noise = NoiseModel(np.array([60.4, 82.7]))
    noise.update(
        Moments(np.array([[3e5, 5e4], [5e4, 4e5]]) * n, np.zeros(2), n, 0), np.zeros(2), np.array([n])
    )
    return rows, sums, comp.fit(sums), noise


def test_one_segment_is_the_papers_closed_form_and_online_equals_refresh() -> None:
    n = 50
    rows, sums, fit, noise = _setup(n, np.zeros(n, int))
    chain = SegmentChain(SUR.A, PRIOR, PRIOR)
    chain.start(0)
    chain.refresh(sums, fit, noise)
    # Sigma' = (Sigma_X^-1 + sum A' R_w^-1 A)^-1, mu' = Sigma' sum A' R_w^-1 (y_w - u0), R_w = Rs / sqrt(m m')
    rs_inv = np.linalg.inv(noise.run_cov(n))
    info, eta = np.linalg.inv(PRIOR), np.zeros(2)
    for mi, yi in zip(rows.m, rows.y, strict=True):
        r_inv = rs_inv * np.sqrt(np.outer(mi, mi))
        info += SUR.A.T @ r_inv @ SUR.A
        eta += SUR.A.T @ r_inv @ yi
    cov = np.linalg.inv(info)
    np.testing.assert_allclose(chain.x, cov @ eta, rtol=1e-9)
    np.testing.assert_allclose(chain.P, cov, rtol=1e-9)
    online = SegmentChain(SUR.A, PRIOR, PRIOR)
    online.start(0)
    online.use_noise(noise)
    for mi, yi in zip(rows.m, rows.y, strict=True):
        online.accept(mi, yi)
    np.testing.assert_allclose(online.x, chain.x, rtol=1e-9)
    np.testing.assert_allclose(online.P, chain.P, rtol=1e-9)


def test_two_segments_with_a_jump_equal_the_dense_joint_gaussian() -> None:
    n = 80
    seg = (np.arange(n) >= 30).astype(int)
    rows, sums, fit, noise = _setup(n, seg, seed=3)
    jump = np.diag([2e-3, 3e-3]) ** 2
    chain = SegmentChain(SUR.A, PRIOR, jump)
    chain.start(0)
    chain.open_segment(30)
    chain.refresh(sums, fit, noise)
    # joint Gaussian over (x1, x2): x1 ~ N(0, P), x2 - x1 ~ N(0, J), windows of each segment
    info = np.zeros((4, 4))
    info[:2, :2] += np.linalg.inv(PRIOR)
    d = np.hstack([-np.eye(2), np.eye(2)])
    info += d.T @ np.linalg.inv(jump) @ d
    eta = np.zeros(4)
    for s in range(2):
        rs_inv = np.linalg.inv(noise.run_cov(int((seg == s).sum())))
        sl = slice(2 * s, 2 * s + 2)
        for mi, yi in zip(rows.m[seg == s], rows.y[seg == s], strict=True):
            r_inv = rs_inv * np.sqrt(np.outer(mi, mi))
            info[sl, sl] += SUR.A.T @ r_inv @ SUR.A
            eta[sl] += SUR.A.T @ r_inv @ yi
    cov = np.linalg.inv(info)
    np.testing.assert_allclose(chain.x, (cov @ eta)[2:], rtol=1e-8)
    np.testing.assert_allclose(chain.P, cov[2:, 2:], rtol=1e-8)
    assert len(chain.summaries) == 2 and chain.summaries[1].windows == n - 30


def test_float_helpers_equal_numpy() -> None:
    rng = np.random.default_rng(0)
    a = rng.normal(size=(2, 2))
    m = a @ a.T + np.eye(2)
    t = rng.normal(size=(2, 2))
    v = rng.normal(size=2)
    sym = (m[0, 0], m[0, 1], m[1, 1])
    np.testing.assert_allclose(np.array(inv_sym(sym))[[0, 1, 2]], np.linalg.inv(m)[[0, 0, 1], [0, 1, 1]])
    np.testing.assert_allclose(quad_inv(sym, tuple(v)), v @ np.linalg.solve(m, v))
    np.testing.assert_allclose(sym_vec(sym, tuple(v)), m @ v)
    np.testing.assert_allclose(mat_vec(tuple(t.ravel()), tuple(v)), t @ v)
    np.testing.assert_allclose(
        np.array(congruence(tuple(t.ravel()), sym)), (t @ m @ t.T)[[0, 0, 1], [0, 1, 1]]
    )


def test_a_provisional_segment_is_the_exact_mixture_of_changed_and_unchanged() -> None:
    """After a gap the posterior is the two-hypothesis mixture, computed here from every window.

    Independent implementation: the evidence of all windows under "no change" (one x for both
    segments) and "change" (x2 = x1 + j, j ~ N(0, J)) from the dense joint Gaussians, the posterior
    of each, and the moments of their mixture with the prior probability 0.3 of a change.
    """
    from scipy.stats import multivariate_normal

    n, n1 = 60, 35
    seg = (np.arange(n) >= n1).astype(int)
    jump = np.diag([2e-3, 3e-3]) ** 2
    for shift, seed in ((0.0, 1), (4e-4, 2), (2e-3, 3)):  # no change, a small one, a clear one
        rows, sums, fit, noise = _setup(n, np.zeros(n, int), seed=seed)  # one state throughout
        rows.seg = seg.astype(np.int64)
        rows.y[seg == 1] += SUR.A @ np.array([shift, -shift])  # ... unless it changes across the gap
        sums = FitSums(sums.q)
        sums.add(rows)
        chain = SegmentChain(SUR.A, PRIOR, jump)
        chain.start(0)
        chain.open_segment(n1, kind="gap", change_prior=0.3)
        chain.refresh(sums, fit, noise)
        # window covariances: the segment's AR(1) run covariance over the samples of each window
        blocks = []
        for s in range(2):
            rs = noise.run_cov(int((seg == s).sum()))
            blocks += [rs / np.sqrt(np.outer(mi, mi)) for mi in rows.m[seg == s]]
        R = np.zeros((2 * n, 2 * n))
        for i, b in enumerate(blocks):
            R[2 * i : 2 * i + 2, 2 * i : 2 * i + 2] = b
        y = rows.y.ravel()
        H1 = np.zeros((2 * n, 4))
        for i, s in enumerate(seg):
            H1[2 * i : 2 * i + 2, 2 * s : 2 * s + 2] = SUR.A
        H0 = H1[:, :2] + H1[:, 2:]  # one x for both segments
        prior1 = np.block([[PRIOR, PRIOR], [PRIOR, PRIOR + jump]])
        moments, evidence = [], []
        for H, prior in ((H0, PRIOR), (H1, prior1)):
            evidence.append(multivariate_normal(np.zeros(2 * n), H @ prior @ H.T + R).logpdf(y))
            r_inv = np.linalg.inv(R)  # information form: well conditioned, unlike inverting S
            post = np.linalg.inv(np.linalg.inv(prior) + H.T @ r_inv @ H)
            moments.append(((post @ H.T @ r_inv @ y)[-2:], post[-2:, -2:]))
        p = 1.0 / (1.0 + (0.7 / 0.3) * np.exp(evidence[0] - evidence[1]))
        (x0, c0), (x1, c1) = moments
        mean = (1 - p) * x0 + p * x1
        cov = (1 - p) * c0 + p * c1 + p * (1 - p) * np.outer(x1 - x0, x1 - x0)
        np.testing.assert_allclose(chain.change_probability, p, rtol=1e-6, atol=1e-9)
        np.testing.assert_allclose(chain.x, mean, rtol=1e-6, atol=1e-12)
        np.testing.assert_allclose(chain.P, cov, rtol=1e-6, atol=1e-16)
        if shift == 0.0:
            assert p < 0.2
        if shift == 2e-3:
            assert p > 0.999


def _curve_case(seed: int) -> tuple[list[SegmentData], np.ndarray, np.ndarray, np.ndarray]:
    """Three segments whose levels share a curve error of about 3 kN: data, curve_cov, H (3, 2, 2q)."""
    rng = np.random.default_rng(seed)
    q = 4
    half = rng.normal(size=(2, q, q))
    curve_cov = (half @ half.transpose(0, 2, 1) + 0.1 * np.eye(q)) * 1.5e6  # N^2
    a_inv = np.linalg.inv(SUR.A)
    data, hs = [], []
    for _ in range(3):
        v = rng.normal(size=(2, q))
        half = rng.normal(size=(2, 2)) * 3e-4
        lam_inv = half @ half.T + np.eye(2) * 1e-8
        data.append(SegmentData(40, rng.normal(size=2) * 1e-3, lam_inv, None, v))
        hs.append(np.hstack([np.outer(a_inv[:, c], v[c]) for c in range(2)]))  # x_d's error H dbeta
    sigma = np.zeros((2 * q, 2 * q))
    sigma[:q, :q], sigma[q:, q:] = curve_cov
    return data, curve_cov, np.array(hs), sigma


def _stacked_cov(data: list[SegmentData], hs: np.ndarray, sigma: np.ndarray, jumps: list[np.ndarray]):
    """Dense covariance of the stacked ``x_d`` (6, 6) and of each ``x_d`` with the last state (6, 2)."""
    n = len(data)
    state = [PRIOR + sum(jumps[1 : s + 1], np.zeros((2, 2))) for s in range(n)]  # Var(x_s)
    cov = np.zeros((2 * n, 2 * n))
    with_last = np.zeros((2 * n, 2))
    for s in range(n):
        for t in range(n):
            cov[2 * s : 2 * s + 2, 2 * t : 2 * t + 2] = state[min(s, t)] + hs[s] @ sigma @ hs[t].T
        cov[2 * s : 2 * s + 2, 2 * s : 2 * s + 2] += data[s].lam_inv
        with_last[2 * s : 2 * s + 2] = state[s]  # Cov(x_s, x_last) = Var(x_s), s <= last
    return cov, with_last, state[-1]


def _weights(chain: SegmentChain, data: list[SegmentData], curve_cov: np.ndarray) -> np.ndarray:
    """The chain's mean as a linear map of the stacked ``x_d`` (2, 6), column by column."""
    cols = []
    for i in range(2 * len(data)):
        unit = np.zeros(2 * len(data))
        unit[i] = 1e-3
        moved = [dataclasses.replace(d, x_d=unit[2 * s : 2 * s + 2]) for s, d in enumerate(data)]
        chain.run_chain(moved, curve_cov)
        cols.append(chain.x / 1e-3)
    return np.array(cols).T


def test_a_curve_error_shared_by_the_segments_is_carried_once() -> None:
    """The levels share one curve error: P is the true error covariance, p the innovation's odds.

    The chain (Schmidt's consider filter) publishes its estimate's true error covariance, and
    after a gap it weighs the two outcomes by the likelihood of the new level given what the
    common error already explains.

    Independent reference: the dense joint Gaussian of the three segments' measurements
    ``x_d,s = x_s + H_s dbeta + w_s``; the chain's mean is linear in them (weights by unit
    measurements), so its error covariance and its innovation's follow from the dense covariance.
    """
    data, curve_cov, hs, sigma = _curve_case(4)
    jump = np.diag([2e-3, 3e-3]) ** 2
    chain = SegmentChain(SUR.A, PRIOR, jump)
    chain.start(0)
    chain.open_segment(40)
    chain.open_segment(80)
    chain.run_chain(data, curve_cov)
    x, P = chain.x, chain.P
    W = _weights(chain, data, curve_cov)
    np.testing.assert_allclose(W @ np.concatenate([d.x_d for d in data]), x, rtol=1e-9)
    cov, with_last, var_last = _stacked_cov(data, hs, sigma, chain.jumps)
    err = W @ cov @ W.T - W @ with_last - with_last.T @ W.T + var_last  # Var(W x_d - x_last)
    np.testing.assert_allclose(P, err, rtol=1e-8)
    naive = cov.copy()  # the same levels with the curve's error counted independently per segment
    for s in range(3):
        for t in range(3):
            if s != t:
                naive[2 * s : 2 * s + 2, 2 * t : 2 * t + 2] -= hs[s] @ sigma @ hs[t].T
    assert not np.allclose(P, W @ naive @ W.T - W @ with_last - with_last.T @ W.T + var_last, rtol=1e-3)

    # the last segment after a gap: p from the innovation x_d,2 - m under both outcomes
    from scipy.stats import multivariate_normal

    for shift in (0.0, 3e-3):
        gap = SegmentChain(SUR.A, PRIOR, jump)
        gap.start(0)
        gap.open_segment(40)
        gap.open_segment(80, kind="gap", change_prior=0.3)
        two = SegmentChain(SUR.A, PRIOR, jump)
        two.start(0)
        two.open_segment(40)
        two.run_chain(data[:2], curve_cov)
        m = two.x  # the posterior before the gap
        moved = [*data[:2], dataclasses.replace(data[2], x_d=m + shift)]
        gap.run_chain(moved, curve_cov)
        lin = np.hstack([-_weights(two, data[:2], curve_cov), np.eye(2)])  # x_d,2 - m
        r = moved[2].x_d - m
        logs = []
        for jumps in ([np.zeros((2, 2)), jump, np.zeros((2, 2))], [np.zeros((2, 2)), jump, jump]):
            c, _, _ = _stacked_cov(data, hs, sigma, jumps)
            logs.append(multivariate_normal(np.zeros(2), lin @ c @ lin.T).logpdf(r))
        p = 1.0 / (1.0 + (0.7 / 0.3) * np.exp(logs[0] - logs[1]))
        np.testing.assert_allclose(gap.change_probability, p, rtol=1e-7, atol=1e-12)
        assert (p > 0.99) if shift else (p < 0.3)


def test_a_lowering_right_after_a_logger_outage_is_confirmed_by_two_windows() -> None:
    """``mark_outage``: three windows confirm a lowering that starts where the data had stopped.

    The same three windows do not confirm it where the data ran on (``event_confirm_windows`` = 4),
    nor a raise after the outage (a vehicle adds load); marks below every segment that may still
    ask are dropped when a later segment opens.
    """
    n, n1 = 60, 57
    seg = (np.arange(n) >= n1).astype(int)
    for shift, marked, confirmed in ((-2e-3, False, False), (-2e-3, True, True), (2e-3, True, False)):
        rows, sums, fit, noise = _setup(n, np.zeros(n, int), seed=4)
        rows.seg = seg.astype(np.int64)
        rows.y[seg == 1] += SUR.A @ np.array([shift, shift])
        sums = FitSums(sums.q)
        sums.add(rows)
        chain = SegmentChain(SUR.A, PRIOR, PRIOR)
        chain.start(0)
        if marked:
            chain.mark_outage(n1)
        chain.mark_outage(10)  # an earlier outage, inside the first segment
        chain.open_segment(n1, kind="held_run", change_prior=0.5)
        chain.refresh(sums, fit, noise)
        assert chain.segment_probability(1)[0] > 0.999
        assert chain.confirms(1, 0.99, 4) is confirmed
        assert chain.confirms(1, 0.99, 3)  # three windows of it whatever the rule
        assert chain.outage_starts == ({n1} if marked else set())  # the earlier mark pruned
        state = chain.state_dict()
        again = SegmentChain(SUR.A, PRIOR, PRIOR)
        again.load_state_dict(state)
        assert again.outage_starts == chain.outage_starts


def test_a_change_is_read_against_the_covariance_of_the_difference() -> None:
    """``change_chi2``: a segment's data estimate less the previous one's, against that difference.

    Independent reference: the dense covariance of the stacked measurements under no change (the
    state common to both, so only the noise and the curve's error as the two read it differently
    remain), ``E C E'`` for ``E = [-I, I]``. A curve error shared by the segments mostly cancels: the
    chi-square is larger than with each segment's whole covariance added. ``confirms`` asks it to
    reach ``min_chi2``.
    """
    data, curve_cov, hs, sigma = _curve_case(4)
    chain = SegmentChain(SUR.A, PRIOR, np.diag([2e-3, 3e-3]) ** 2)
    chain.start(0)
    chain.open_segment(40)
    chain.open_segment(80)
    chain.run_chain(data, curve_cov)
    cov, _, _ = _stacked_cov(data, hs, sigma, [np.zeros((2, 2))] * 3)
    for s in (1, 2):
        E = np.zeros((2, 6))
        E[:, 2 * s - 2 : 2 * s], E[:, 2 * s : 2 * s + 2] = -np.eye(2), np.eye(2)
        d = data[s].x_d - data[s - 1].x_d
        expected = float(d @ np.linalg.solve(E @ cov @ E.T, d))
        np.testing.assert_allclose(chain.change_chi2(s), expected, rtol=1e-9)
        whole = [data[t].lam_inv + hs[t] @ sigma @ hs[t].T for t in (s - 1, s)]
        assert chain.change_chi2(s) > float(d @ np.linalg.solve(whole[0] + whole[1], d))
        chi2 = chain.change_chi2(s)
        assert chain.confirms(s, 0.0, 0, min_chi2=0.5 * chi2)
        assert not chain.confirms(s, 0.0, 0, min_chi2=2.0 * chi2)
    assert np.isnan(chain.change_chi2(0)) and np.isnan(chain.change_chi2(5))
    again = SegmentChain(SUR.A, PRIOR, np.diag([2e-3, 3e-3]) ** 2)
    again.load_state_dict(chain.state_dict())
    np.testing.assert_allclose(again.change_chi2(2), chain.change_chi2(2), rtol=1e-12)

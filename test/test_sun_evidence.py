"""The sun term's evidence (``sun_gradient_fit: deck``): one ``g`` of the deck, in where the data show it.

- One ``g`` read through both bearings equals a joint dense constrained solve (levels, curves, ``g``).
- Its Bayes factor against no term is the marginal likelihood ratio by quadrature, and so is a ``g``
  of each bearing's own; where the factor is below 3, or separate ``g``'s fit better (a pattern
  one bearing shows and the other contradicts), the fit is the one without the sun column.
- On the bundled demo (the twin's 4 K vertical and 3 K transverse sun) the bearings' sun differs:
  the term stays out, and says why. The real morning pair: out, and the run without the term.
- A common-mode settlement and the deck's vertical difference load the two bearings alike (the
  surrogate's ``A [1, 1]`` and ``thermal.vertical_gradient`` in the same ratio): only the time
  course tells them apart; the shipped fit averages the term by its evidence (test_sun_average.py).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.interpolate import BSpline
from sun_helpers import assert_chunks_and_checkpoint_change_nothing, sun_rows

from bridge_shadow.estimate import Shadow, load_config
from bridge_shadow.estimate.compensation.fit import Compensation
from bridge_shadow.estimate.compensation.spline import gram_penalty, gram_slope
from bridge_shadow.estimate.compensation.sums import FitSums, WindowRows
from bridge_shadow.model.surrogate_file import load_surrogate


def _dense_reference(comp: Compensation, rows: WindowRows, s: np.ndarray, lam: float, kappa: np.ndarray):
    """Minimise the fit's objective for both channels at once by a dense KKT solve, one ``g``.

    Per channel ``sum m (y - l_seg - b'beta - slope g s)^2 + lam beta'Omega beta + kap int (g' -
    s_fe)^2`` over its per-sample variance ``sigma^2 = kap slope_sd^2``, both plus the prior
    ``(g - g0)^2 / sd_g^2``, subject to ``sum m b'beta = 0`` per channel (the curve centred, the
    sun not). Returns each channel's levels and spline coefficients, and ``g``.
    """
    n_seg = int(rows.seg.max()) + 1
    blocks, rhss, cons = [], [], []
    for c in range(2):
        basis = BSpline.design_matrix(np.clip(rows.t[:, c], comp.t_min, comp.t_max), comp.knots, 3).toarray()
        q = basis.shape[1]
        sigma2 = kappa[c] * comp.slope_sd**2
        x = np.column_stack([np.eye(n_seg)[rows.seg], basis, comp.sun_slope[c] * s])
        w = rows.m[:, c] / sigma2
        p = n_seg + q + 1
        pen = np.zeros((p, p))
        pen[n_seg : n_seg + q, n_seg : n_seg + q] = lam * gram_penalty(comp.knots) + kappa[c] * gram_slope(
            comp.knots
        )
        e = np.zeros(p)
        e[n_seg], e[n_seg + q - 1] = -1.0, 1.0
        blocks.append(x.T @ (w[:, None] * x) + pen / sigma2)
        rhss.append(x.T @ (w * rows.y[:, c]) + kappa[c] * comp.slope_fe[c] * e / sigma2)
        con = np.zeros(p)
        con[n_seg : n_seg + q] = rows.m[:, c] @ basis
        cons.append(con)
    # unknowns: channel 0's levels and spline, channel 1's, then g (both channels' last column)
    p = len(rhss[0]) - 1
    mat = np.zeros((2 * p + 1, 2 * p + 1))
    rhs = np.zeros(2 * p + 1)
    for c in range(2):
        idx = np.r_[np.arange(c * p, (c + 1) * p), 2 * p]
        mat[np.ix_(idx, idx)] += blocks[c]
        rhs[idx] += rhss[c]
    g0, sd_g = comp.sun_prior_k
    mat[-1, -1] += 1.0 / sd_g**2
    rhs[-1] += g0 / sd_g**2
    con = np.zeros((2, 2 * p + 1))
    con[0, :p], con[1, p : 2 * p] = cons[0][:-1], cons[1][:-1]
    kkt = np.block([[mat, con.T], [con, np.zeros((2, 2))]])
    sol = np.linalg.solve(kkt, np.r_[rhs, 0.0, 0.0])
    chans = [(sol[c * p : c * p + n_seg], sol[c * p + n_seg : (c + 1) * p]) for c in range(2)]
    return chans, sol[2 * p]


@pytest.mark.parametrize("mean", [-40.0, -3.0, -0.5, 0.0, 0.7, 5.0, 60.0])
def test_the_truncated_density_at_zero_is_scipy_stats_norm(mean: float) -> None:
    """The Savage-Dickey ratio's density, on ``scipy.special``, is ``scipy.stats.norm``'s (deep tails too)."""
    from scipy import stats

    from bridge_shadow.estimate.compensation.fit import _log_truncated_density_at_zero

    for sd in (1e-3, 0.2, 1.0, 7.5, 300.0):
        ref = stats.norm.logpdf(0.0, mean, sd) - stats.norm.logsf(0.0, mean, sd)
        assert np.isfinite(ref)
        np.testing.assert_allclose(_log_truncated_density_at_zero(mean, sd), ref, rtol=1e-13, atol=1e-13)


def test_one_g_of_the_deck_equals_a_joint_dense_constrained_solve() -> None:
    """One ``g`` of the deck for both bearings: the fit equals the joint dense solve, levels and all."""
    slope = np.array([-4000.0, -5000.0])
    comp = Compensation(
        -20.0, 45.0, 13, mode="fixed", slope_fe=np.array([10.0, 12.0]), sun_slope=slope, sun_fit="deck"
    )
    rows, s = sun_rows(comp, 400, 1)
    sums = FitSums(comp.q, comp.width)
    sums.add(rows)
    kappa = np.array([3e-3, 5e-3])
    fit = comp.fit(sums, lam=np.array([50.0, 50.0]), kappa=kappa)
    chans, g = _dense_reference(comp, rows, s, 50.0, kappa)
    assert g > 0.0  # (the mode is inside the prior's half line: no truncation to compare)
    assert fit.sun_evidence[2] == pytest.approx(g, rel=1e-7)
    for c in range(2):
        levels, beta = chans[c]
        np.testing.assert_allclose(fit.beta[c, :-1], beta, rtol=1e-7, atol=1e-6 * np.abs(beta).max())
        assert fit.beta[c, -1] == pytest.approx(slope[c] * g, rel=1e-8)
        np.testing.assert_allclose(fit.level[:, c], levels, rtol=1e-8)
    # the data's sun (-3000 / -4000 N at s = 1: 0.75 / 0.8 K) is found; the prior (mean 0) barely pulls
    assert g == pytest.approx(0.78, abs=0.03)
    # with one segment the sun coefficient's uncertainty still reaches the level (it is not centred)
    one = FitSums(comp.q, comp.width)
    rows.seg[:] = 0
    one.add(rows)
    assert np.all(comp.fit(one, kappa=kappa).beta_variance_factor(one, 0) > 0)


def _profile_misfit(comp: Compensation, rows: WindowRows, s: np.ndarray, c: int, lam: float, kap: float):
    """Return ``Q(gamma)``: the fit's objective without the sun prior, minimised with ``gamma`` held.

    Dense: levels and spline coefficients by a KKT solve on ``y - gamma s`` (the curve centred).
    """
    basis = BSpline.design_matrix(np.clip(rows.t[:, c], comp.t_min, comp.t_max), comp.knots, 3).toarray()
    n_seg = int(rows.seg.max()) + 1
    q = basis.shape[1]
    x = np.column_stack([np.eye(n_seg)[rows.seg], basis])
    w = rows.m[:, c]
    p = n_seg + q
    pen = np.zeros((p, p))
    pen[n_seg:, n_seg:] = lam * gram_penalty(comp.knots) + kap * gram_slope(comp.knots)
    e = np.zeros(p)
    e[n_seg], e[-1] = -1.0, 1.0
    con = np.zeros(p)
    con[n_seg:] = w @ basis
    kkt = np.block([[x.T @ (w[:, None] * x) + pen, con[:, None]], [con[None, :], np.zeros((1, 1))]])
    s_fe = comp.slope_fe[c]

    def q_of(gamma: float) -> float:
        y = rows.y[:, c] - gamma * s
        theta = np.linalg.solve(kkt, np.r_[x.T @ (w * y) + kap * s_fe * e, 0.0])[:p]
        r = y - x @ theta
        beta = theta[n_seg:]
        slope_misfit = beta @ gram_slope(comp.knots) @ beta - 2 * s_fe * (beta[-1] - beta[0])
        return float(w @ r**2 + lam * beta @ gram_penalty(comp.knots) @ beta + kap * slope_misfit)

    return q_of


@pytest.mark.parametrize(
    ("sun_n", "used"), [((-3000.0, -4000.0), True), ((0.0, 0.0), False), ((3000.0, -8000.0), False)]
)
def test_the_sun_terms_bayes_factor_is_the_marginal_likelihood_ratio(sun_n, used) -> None:
    """``sun_log_bf`` is ``ln p(y | term) / p(y | no term)`` for one ``g`` of the deck, by quadrature.

    Independent of the fit's algebra: ``p(y | g) / p(y | 0) = exp(-(Q(gamma) - Q(0)) / 2 sigma^2)``
    per bearing (``Q`` minimised over the levels and the curve, dense, with the sun held;
    ``gamma = slope g``, the other coefficients' Gaussian integral not depending on it), times the
    prior of ``g`` (half-normal on ``g >= 0``), integrated over ``g``; for a ``g`` of each bearing's
    own, each integrated alone. With the data's sun the term is used; without it the factor is
    below 3, and with a sun of the wrong sign in one bearing (a pattern the other bearing's sun
    does not explain) separate ``g``'s fit better than one: in both the fit is the one without
    the sun column.
    """
    from scipy import integrate, stats

    slope = np.array([-4000.0, -5000.0])
    kw = {"mode": "fixed", "slope_fe": np.array([10.0, 12.0])}
    comp = Compensation(-20.0, 45.0, 13, sun_slope=slope, sun_min_bf=3.0, sun_fit="deck", **kw)
    plain = Compensation(-20.0, 45.0, 13, **kw)
    rows, s = sun_rows(comp, 300, 4)
    rows.y += np.outer(s, np.asarray(sun_n) - (-3000.0, -4000.0))  # (_rows puts -3000 / -4000 N in)
    sigma = np.array([4.0e4, 5.0e4])  # N per sample: window means within a few kN of the sun's
    rows.y += np.random.default_rng(5).normal(0.0, 1.0, rows.y.shape) * sigma / np.sqrt(rows.m)
    sums = FitSums(comp.q, comp.width)
    sums.add(rows)
    sigma2 = sigma**2
    kappa = comp.slope_weight(sigma2)  # the priors weighed on the noise's per-sample variance
    lam = np.array([50.0, 50.0])
    fit = comp.fit(sums, lam=lam, kappa=kappa)
    qs = [_profile_misfit(comp, rows, s, c, 50.0, float(kappa[c])) for c in range(2)]
    q0 = [q(0.0) for q in qs]
    m0, sd0 = comp.sun_prior_k

    def log_bf(chans: tuple[int, ...]) -> float:
        def log_like(g: float) -> float:
            return sum(-(qs[c](slope[c] * g) - q0[c]) / (2.0 * sigma2[c]) for c in chans)

        top = max(log_like(g) for g in np.linspace(0.0, 4.0 * sd0, 81))  # (scaled out of the integral)

        def integrand(g: float) -> float:
            return float(np.exp(log_like(g) - top)) * stats.norm.pdf(g, m0, sd0) / stats.norm.sf(0.0, m0, sd0)

        bf, _ = integrate.quad(
            integrand, 0.0, 8.0 * sd0, points=[0.5, 1.0, 2.0, 4.0], limit=200, epsrel=1e-10
        )
        return float(np.log(bf) + top)

    assert fit.sun_log_bf == pytest.approx(log_bf((0, 1)), abs=1e-6)
    assert fit.sun_evidence[1] == pytest.approx(log_bf((0,)) + log_bf((1,)), abs=1e-6)
    assert fit.sun_used is used
    assert bool(fit.sun_log_bf >= np.log(3.0) and fit.sun_log_bf >= fit.sun_evidence[1]) is used
    if sun_n[0] > 0:  # the contradicted case: one g alone would have passed the factor of 3
        assert fit.sun_log_bf >= np.log(3.0)
    if used:
        same = Compensation(-20.0, 45.0, 13, sun_slope=slope, sun_min_bf=0.0, sun_fit="deck", **kw)
        same = same.fit(sums, lam=lam, kappa=kappa)
        np.testing.assert_allclose(fit.beta, same.beta, rtol=1e-12)
        return
    ref_sums = FitSums(plain.q, plain.width)
    ref_rows, _ = sun_rows(plain, 300, 4)
    ref_rows.y[:] = rows.y
    ref_sums.add(ref_rows)
    ref = plain.fit(ref_sums, lam=lam, kappa=kappa)
    assert np.all(fit.beta[:, -1] == 0.0) and np.all(fit.minv[:, -1, :] == 0.0)  # set, not computed
    np.testing.assert_allclose(fit.beta[:, :-1], ref.beta, rtol=1e-9, atol=1e-9 * np.abs(ref.beta).max())
    np.testing.assert_allclose(fit.level, ref.level, rtol=1e-10)
    np.testing.assert_allclose(
        fit.minv[:, :-1, :-1], ref.minv, rtol=1e-8, atol=1e-12 * np.abs(ref.minv).max()
    )
    np.testing.assert_allclose(fit.edf, ref.edf, rtol=1e-10)


def test_the_bundled_demo_with_one_g_of_the_deck_leaves_the_term_out_and_says_why(
    root: Path, tmp_path: Path
) -> None:
    """``bags/demo_3d``'s sun differs between the bearings (3 K transverse): one ``g`` is not the deck's.

    A ``g`` of each bearing's own (``per_bearing``, ``test_sun_term``) takes the vertical and the
    transverse difference together; one ``g`` of the deck cannot, so separate ``g``'s explain the
    bearings better, however strong the sun: the term stays out, and the text says why.
    """
    import contextlib
    import io
    import json

    from bridge_shadow.cli import main

    params = tmp_path / "deck.yaml"
    params.write_text(
        "bridge_shadow:\n  ros__parameters:\n    sun_gradient: true\n    sun_gradient_fit: deck\n"
    )
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["replay", str(root / "bags" / "demo_3d"), "--params", str(params), "--json"]) == 0
    js = json.loads(out.getvalue())
    text = io.StringIO()
    with contextlib.redirect_stdout(text):
        assert main(["replay", str(root / "bags" / "demo_3d"), "--params", str(params)]) == 0
    assert text.getvalue().count("sun term not used (Bayes factor e^") == 2
    assert "a g of each bearing's own fits better" in text.getvalue()
    for sp in js["spline"].values():
        assert sp["sun_gradient_used"] is False and sp["sun_gradient_k"] == 0.0  # set: the term out
        assert sp["sun_gradient_log_bf"] > 100.0  # one g is far likelier than none ...
        assert (
            sp["sun_gradient_log_bf_per_bearing"] > sp["sun_gradient_log_bf"]
        )  # ... a g each likelier still


@pytest.mark.realdata
def test_the_real_morning_pair_with_one_g_of_the_deck_is_the_run_without_the_term(munich_data: Path) -> None:
    """The 2022-04-11 pair (28 minutes of morning data): a factor below 3, the term out, nothing moved."""
    from bridge_shadow.importers import import_csv

    folder = munich_data / "Settlements"
    april, _ = import_csv(
        [
            folder / "UniBw_2022-04-11_ref_support_load_01ForceAt100Hz.csv.zip",
            folder / "UniBw_2022-04-11_support_load_01ForceAt100Hz.csv.zip",
            folder / "TemperatureData2022-04-11.zip",
        ]
    )
    deck = Shadow(load_config().replace(sun_gradient=True, sun_gradient_fit="deck"), load_surrogate())
    res = deck.run(april)
    off = Shadow(load_config().replace(sun_gradient=False), load_surrogate()).run(april)
    assert not deck.fit.sun_used and deck.fit.sun_log_bf < np.log(3.0)
    np.testing.assert_allclose(res.mean_m, off.mean_m, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(res.covariance_m2, off.covariance_m2, rtol=1e-9, atol=1e-18)


def test_a_common_mode_settlement_loads_the_bearings_as_the_decks_vertical_difference_does() -> None:
    """The shipped surrogate: ``A [1, 1]`` and ``thermal.vertical_gradient`` in one ratio (within 1 %).

    Both act on the continuous girder through the central support's redundant reaction, shared by
    the two bearings side by side in the same proportion. Read from the reactions alone, a step of
    both supports inside a record looks like the sun's difference growing: only the time course
    (a step, against the sun's smooth rise) tells them apart.
    """
    sur = load_surrogate()
    settle = sur.A @ np.ones(2)
    vertical = np.asarray(sur.thermal["vertical_gradient"], float)
    assert settle[0] / settle[1] == pytest.approx(vertical[0] / vertical[1], rel=0.01)
    transverse = np.asarray(sur.thermal["transverse_gradient"], float)
    assert transverse[0] * transverse[1] < 0  # the transverse difference is told apart: opposite signs


def test_one_g_of_the_deck_learns_a_vertical_sun_and_survives_chunks_and_a_checkpoint(tmp_path: Path) -> None:
    """Three sunny days of twin monitoring (4 K vertical only): the term is in, ``g`` near 4 K.

    Its evidence, the fit it decides and the posterior are the same fed in chunks, and stopped at
    the middle, checkpointed and resumed (``sun_evidence`` travels in the checkpoint).
    """
    from bridge_shadow.twin.simulate import simulate

    data, truth = simulate(3.0, 0.1, 2, {"settlement_offset": 7e-4, "vertical_gradient": 4.0})
    sur = load_surrogate()
    cfg = load_config().replace(
        sun_gradient=True, sun_gradient_fit="deck", checkpoint_path=str(tmp_path / "s.npz")
    )
    whole_shadow = Shadow(cfg, sur)
    whole = whole_shadow.run(data)
    fit = whole_shadow.fit
    assert fit.sun_used and fit.sun_log_bf > np.log(1e3)
    g = fit.beta[:, -1] / sur.thermal["vertical_gradient"]
    assert g[0] == pytest.approx(g[1], rel=1e-12) and g[0] == pytest.approx(4.0, abs=0.5)
    sd = np.sqrt(np.diag(whole.covariance_m2))
    assert np.all(np.abs(whole.mean_m - np.array(truth["settlement"]["end_m"])) <= 1.96 * sd)
    assert_chunks_and_checkpoint_change_nothing(cfg, sur, data, whole, tmp_path)

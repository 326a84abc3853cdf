"""Temperature compensation fitted jointly with the settlement levels, so it cannot absorb a settlement.

Per channel the window means follow ``y_w - u0 = l_s(w) + g(T_w) + e_w``: a level ``l_s`` per
settlement segment (segments are separated by detected events; ``l_s = A x_s`` plus the mean
thermal response) and one smooth curve ``g`` shared by all segments. The fit is a penalized
least-squares problem with weights ``m_w`` (samples per window):

    min  sum_w m_w (y_w - l_s(w) - b_w' beta)^2 + lambda int g''^2 dT + kappa int (g' - s_FE)^2 dT

- Profiling the levels out leaves the within-segment sums ``Gw = G - sum_s sb_s sb_s' / W_s`` and
  ``rw = r - sum_s sb_s sy_s / W_s`` (``FitSums``): the curve is fitted on the variation *inside*
  segments only, so a step between segments, at whatever temperature, stays in the levels.
- ``g`` is centred, ``sum_w m_w g(T_w) = 0`` over all windows (the paper's ``y - g(T) + ybar``: the
  level belongs to the settlement). The constant direction (B-splines sum to one) is in the null
  space of ``Gw`` and ``Omega``; adding ``sb sb' / W`` to the matrix fixes it at ``sb' beta = 0``.
- ``kappa int (g' - s_FE)^2 dT`` is a prior on the slope, centred on the FE uniform-temperature
  sensitivity ``s_FE = surrogate.thermal['uniform']`` (N/K): where the data say nothing (between
  temperature clusters of different segments, in a narrow range of a few windows) ``g`` follows
  the FE slope, and the change of ``g`` across a gap of ``D`` kelvin has a prior standard
  deviation of about ``thermal_prior_sd_n_per_k * sqrt(D / 1 K)``: ``kappa = sigma^2 / sd^2 * 1 K``
  with ``sigma^2`` the noise model's per-sample variance (the data term's scale; the marginal one,
  so that a misfit that the noise model takes for slow noise cannot pin the curve to the prior). A
  day of data outweighs it by orders of magnitude. (``beta' Omega1 beta = int g'^2``, exact.)
- Outside the temperature range seen so far ``g`` continues with the FE slope from the edge,
  never with a trend extrapolated from a few windows.
- ``lambda`` is chosen by REML (or GCV) on the profiled sums, the slope prior counted as data, in
  the basis orthogonal to the constant, with ``n - S`` observations (S levels profiled out).

Levels of the fit: ``l_s = (sy_s - sb_s' beta) / W_s``. The curve's own uncertainty reaches a
segment level through ``v_s = sb_s / W_s - sb / W`` (zero with one segment):
``var_beta(l_s) = sigma^2 v_s' M^-1 v_s`` (Bayesian P-spline posterior, ``M`` the matrix above).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import linalg, special

from bridge_shadow.errors import ConfigError
from bridge_shadow.estimate.compensation.spline import (
    basis_nonzero,
    clamped_knots,
    gram_penalty,
    gram_slope,
    nonzero_at,
    select_lambda,
)
from bridge_shadow.estimate.compensation.sums import FitSums, row_columns

__all__ = ["Compensation", "CompensationFit", "deck_sun_weight"]


#: ``ln sqrt(2 pi)``, as ``scipy.stats.norm`` computes it.
_LOG_SQRT_2PI = float(np.log(np.sqrt(2 * np.pi)))


def _log_truncated_density_at_zero(mean: float, sd: float) -> float:
    """``ln`` of the density at 0 of ``N(mean, sd^2)`` truncated to ``[0, inf)``.

    ``scipy.stats.norm.logpdf(0, mean, sd) - scipy.stats.norm.logsf(0, mean, sd)`` with its own
    formulas on its own ``scipy.special`` kernel, without its argument checks (a hundred
    microseconds a call, on every refit; ``test_sun_evidence`` compares the two).
    """
    z = (0.0 - mean) / sd
    return float((-z * z / 2.0 - _LOG_SQRT_2PI - math.log(sd)) - special.log_ndtr(-z))


def _log_savage_dickey(m0: float, s0: float, mu: float, sd: float) -> float:
    """``ln`` of the prior's over the posterior's density at ``g = 0``, both truncated to ``g >= 0``."""
    return _log_truncated_density_at_zero(m0, s0) - _log_truncated_density_at_zero(mu, sd)


def _no_evidence() -> np.ndarray:
    """Return the sun evidence of a fit that has none (``CompensationFit.sun_evidence``): four NaNs."""
    return np.full(4, np.nan)


def deck_sun_weight(evidence: np.ndarray) -> float:
    """Return the probability of one ``g`` of the deck among three explanations (NaN: no evidence).

    No sun term, one ``g`` of the deck, a ``g`` of each bearing's own, equally likely before the
    data; ``evidence`` is ``CompensationFit.sun_evidence`` (``ln`` of the Bayes factors of the
    latter two against none first): ``B_d / (1 + B_d + B_s)``.
    """
    log_d, log_s = float(evidence[0]), float(evidence[1])
    if not (math.isfinite(log_d) and math.isfinite(log_s)):
        return float("nan")
    top = max(0.0, log_d, log_s)
    return math.exp(log_d - top) / (math.exp(-top) + math.exp(log_d - top) + math.exp(log_s - top))


@dataclass
class CompensationFit:
    """One fit of both channels.

    Attributes:
        beta: (2, q) N, centred spline coefficients.
        lam: (2,) smoothing parameters (inf: no curve).
        edf: (2,) effective degrees of freedom of the curve (within segments).
        level: (n_seg, 2) N, segment levels ``l_s`` relative to ``u0``.
        dof: (2,) residual degrees of freedom ``n - S - edf``.
        minv: (2, q, q) inverse of the fit matrix ``M`` (for the curve's uncertainty).
        t_lo, t_hi: (2,) C, temperature range the curve was fitted on.
        kappa: (2,) K, the slope prior's weight used.
        mbar: (2, q) ``M^-1 bbar``; sbar: (2,) ``bbar' M^-1 bbar`` (``bbar = sb / W`` on the spline
            columns, 0 on the sun's: the curve is centred, the sun term is not), for the variance.
        n: windows in the fit.
        bbar: (2, q) the centring direction ``bbar``.
        sun: the fit has a sun term (its coefficient is ``beta[:, -1]``, N per unit of the sun covariate).
        sun_evidence: (4,) the sun term's evidence (``Compensation.sun_evidence``): ``ln B10`` of
            one ``g`` for the deck against none, ``ln B`` of separate ones per bearing against
            none, and the mean and sd (K) of ``g``'s posterior (untruncated); NaN where none was
            computed. A term the evidence does not carry is out of the fit (``sun_used``).

    """

    beta: np.ndarray
    lam: np.ndarray
    edf: np.ndarray
    level: np.ndarray
    dof: np.ndarray
    minv: np.ndarray
    t_lo: np.ndarray
    t_hi: np.ndarray
    kappa: np.ndarray
    mbar: np.ndarray
    sbar: np.ndarray
    n: int
    bbar: np.ndarray
    sun: bool = False
    sun_evidence: np.ndarray = field(default_factory=_no_evidence)

    @property
    def sun_used(self) -> bool:
        """The sun term is in this fit (not left out for want of evidence)."""
        return self.sun and bool(np.any(self.minv[:, -1, -1] > 0))

    @property
    def sun_log_bf(self) -> float:
        """``ln B10`` of the sun term (one ``g`` for the deck) against none; NaN: not computed."""
        return float(self.sun_evidence[0])

    def level_directions(self, sums: FitSums, s: int) -> np.ndarray:
        """Return (2, q) ``v_s = sb_s / W_s - bbar`` per channel (level error of segment s: ``-v_s' dbeta``).

        Zero for a channel without windows in the segment (or in the fit), and with one segment
        unless a sun term (not centred) is fitted.
        """
        out = np.zeros((2, self.beta.shape[1]))
        if sums.n_segments < 2 and not self.sun:
            return out
        for c in range(2):
            if sums.Ws[s, c] > 0 and sums.W[c] > 0:
                out[c] = sums.sbs[s, c] / sums.Ws[s, c] - self.bbar[c]
        return out

    def beta_variance_factor(self, sums: FitSums, s: int) -> np.ndarray:
        """Return (2,) ``v_s' M^-1 v_s``: the curve's share of segment ``s``'s level variance / sigma^2."""
        v = self.level_directions(sums, s)
        return np.maximum(np.einsum("ci,cij,cj->c", v, self.minv, v), 0.0)


class Compensation:
    """Joint spline-and-levels fit on ``FitSums`` (no state of its own besides its settings).

    Attributes:
        knots: clamped cubic knot vector; q: basis size; omega: (q, q) curvature penalty.
        mode: ``reml`` | ``gcv`` | ``fixed`` | ``none`` (``none``: no curve, compensated = raw).
        lam_fixed: lambda of ``fixed`` mode.
        slope_fe: (2,) N/K, FE uniform-temperature sensitivity (prior slope and extrapolation).
        slope_sd: N/K, the slope prior's standard deviation over one kelvin.
        omega1: (q, q) slope penalty ``int b' b'^T``; e: (q,) ``int b'`` (``e' beta = g(t_max) - g(t_min)``).
        sun: a sun term is fitted (one more column, the last: ``gamma s(t)``, see below).
        q_spline: B-spline basis size (``q`` less the sun column); width: basis values per row.
        sun_slope: (2,) N/K, the FE response to 1 K of vertical temperature difference.
        sun_prior_k: (mean, sd) K, the prior of the difference at a covariate of 1.

    The sun term (``sun_slope`` given): the deck's sun-driven vertical temperature difference is
    ``dT_v = g s(t)`` with ``s`` the sun covariate (clear-sky irradiance over its yearly peak times
    the day's clearness, ``sunlight.SunCovariate``), its force ``gamma_c s(t)``,
    ``gamma_c = sun_slope_c g``.
    ``gamma`` is fitted with the curve, on the variation inside segments like it, under the prior
    ``g ~ N(sun_prior_k)`` weighed like the slope prior (``sigma^2 / sd_gamma^2``), truncated at
    ``g >= 0``: the sun drives only the top-warmer difference (EN 1991-1-5 6.1.4: the heating case
    ``Delta T_M,heat`` is the solar one; the bottom-warmer ``Delta T_M,cool`` comes with the night
    sky, when ``s`` is 0). The fit is that posterior's mode: where the unconstrained one has
    ``g < 0`` the sun column is held at 0 and the rest refitted (``minv`` stays the unconstrained
    fit's, so the curve's error keeps the sun's uncertainty: on the generous side). It is *not*
    centred: a level is the state without sun (the night), so the sun's mean over the data does
    not end up in the settlement. Days of monitoring fix ``gamma``; short records hours apart do
    not, and then the prior's spread reaches the level differences (``beta_variance_factor``).

    ``sun_fit``: ``per_bearing`` (the above: each channel its own ``gamma_c``, always in; it takes
    any pattern that follows the sun, the transverse difference too) or ``deck``: one ``g`` for both
    channels, ``gamma_c = sun_slope_c g`` at the mode of the product of both channels' posteriors
    (their priors divided out) with one prior, and only where the evidence carries it
    (``sun_evidence``: its Bayes factor at least ``sun_min_bf`` and one ``g`` at least as likely
    as one per channel); else the fit is the one without the sun column. ``minv`` stays each
    channel's own (its sun variance that of the channel's data alone: on the generous side). Or
    ``average`` (shipped): one ``g`` for both channels averaged over no term, the deck's ``g`` and
    one per channel by their Bayes factors (``averaged_sun``): ``gamma_c = sun_slope_c w m``, the
    sun's row and column of each channel's ``minv`` scaled to the mixture's sd.
    """

    def __init__(
        self,
        t_min_c: float,
        t_max_c: float,
        segments: int,
        mode: str = "reml",
        lam: float = 10.0,
        slope_fe: np.ndarray | None = None,
        slope_sd: float = 500.0,
        sun_slope: np.ndarray | None = None,
        sun_prior_k: tuple[float, float] = (0.0, 6.75),
        sun_min_bf: float = 0.0,
        sun_fit: str = "per_bearing",
    ) -> None:
        self.knots = clamped_knots(np.linspace(t_min_c, t_max_c, segments + 1))
        self.t_min, self.t_max = float(self.knots[0]), float(self.knots[-1])
        self._knot_floats = self.knots.tolist()  # the one-window basis (``basis_one``)
        self._fit_floats: tuple[CompensationFit, tuple[list, ...]] | None = None
        self.sun = sun_slope is not None
        self.q_spline = qs = len(self.knots) - 4
        self.q = qs + int(self.sun)
        self.width = 4 + int(self.sun)
        self.sun_slope = np.zeros(2) if sun_slope is None else np.asarray(sun_slope, float).reshape(2)
        self.sun_prior_k = (float(sun_prior_k[0]), float(sun_prior_k[1]))
        if self.sun and not np.all(np.abs(self.sun_slope) > 0):
            raise ConfigError(
                "sun_gradient needs the surrogate's thermal.vertical_gradient (the FE response to a "
                "vertical temperature difference, N/K, non-zero on both bearings); "
                f"it has {self.sun_slope.tolist()}: rebuild it (bridge-shadow surrogate) or set "
                "sun_gradient: false"
            )
        if self.sun and self.sun_prior_k[1] <= 0:
            raise ConfigError(f"sun_gradient_prior_sd_k must be > 0 (now {self.sun_prior_k[1]:g})")
        self.omega = self._pad(gram_penalty(self.knots))
        self.mode = mode
        self.lam_fixed = float(lam)
        self.slope_fe = np.zeros(2) if slope_fe is None else np.asarray(slope_fe, float).reshape(2)
        self.slope_fe_floats = self.slope_fe.tolist()
        self.slope_sd = float(slope_sd)
        self.omega1 = self._pad(gram_slope(self.knots))
        self.e = np.zeros(self.q)
        self.e[0], self.e[qs - 1] = -1.0, 1.0
        self.span = self.t_max - self.t_min
        # the constant curve (B-splines sum to one), and an orthonormal basis orthogonal to it (REML)
        self._one = np.r_[np.ones(qs), np.zeros(self.q - qs)]
        q_full, _ = np.linalg.qr(np.column_stack([self._one, np.eye(self.q)[:, : self.q - 1]]))
        self._z = q_full[:, 1:]
        q_spl, _ = np.linalg.qr(np.column_stack([np.ones(qs), np.eye(qs)[:, : qs - 1]]))
        self._z_spline = q_spl[:, 1:]
        self.sun_min_log_bf = float(np.log(sun_min_bf)) if sun_min_bf > 0 else -np.inf
        if sun_fit not in ("average", "deck", "per_bearing"):
            raise ConfigError(f"sun_gradient_fit must be average, deck or per_bearing (now {sun_fit!r})")
        self.sun_fit = sun_fit

    def _pad(self, mat: np.ndarray) -> np.ndarray:
        """Return a spline-basis matrix with a zero row and column for the sun term, if any."""
        out = np.zeros((self.q, self.q))
        out[: self.q_spline, : self.q_spline] = mat
        return out

    # -- basis ----------------------------------------------------------------------------------
    def basis_rows(self, temp_c: np.ndarray, sun: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Non-zero basis of windows (n, 2): first spline index (n, 2) (-1 if NaN), values (n, 2, width).

        With a sun term the fifth value is the windows' sun covariate ``sun`` (n,)
        (``sunlight.SunCovariate``; None: 0, the curve of temperature alone).
        """
        t = np.asarray(temp_c, float).reshape(-1, 2)
        ok = np.isfinite(t)
        i0, bv = basis_nonzero(
            self.knots, np.minimum(np.maximum(np.where(ok, t, self.t_min), self.t_min), self.t_max)
        )
        i0 = np.where(ok.ravel(), i0, -1).reshape(-1, 2)
        bv = bv.reshape(-1, 2, 4)
        if not self.sun:
            return i0, bv
        s = np.zeros(len(t)) if sun is None else np.asarray(sun, float).reshape(-1)
        return i0, np.concatenate([bv, np.repeat(s[:, None, None], 2, axis=1)], axis=2)

    def basis_one(self, temp: tuple[float, float], sun: float = 0.0) -> tuple[list[int], list[list[float]]]:
        """``basis_rows`` of one window in floats: first spline index (2,) (-1 if NaN), values (2, width).

        The same clipping and recursion (``spline.nonzero_at``), value for value: a live window
        closes one at a time, and numpy's per-call cost made ``basis_rows`` of one row its slowest part.
        """
        i0, bv = [], []
        for t in temp:
            known = math.isfinite(t)
            first, values = nonzero_at(
                self._knot_floats, min(max(t if known else self.t_min, self.t_min), self.t_max), self.q_spline
            )
            i0.append(first if known else -1)
            bv.append([*values, sun] if self.sun else values)
        return i0, bv

    def _floats(self, fit: CompensationFit) -> tuple[list, ...]:
        """Return the fit's arrays the one-window curve reads, as lists (kept for the last fit asked)."""
        if self._fit_floats is None or self._fit_floats[0] is not fit:
            scale = (fit.kappa * self.slope_sd**2).tolist()
            lists = (fit.beta.tolist(), fit.minv.tolist(), fit.mbar.tolist(), fit.sbar.tolist(), scale)
            self._fit_floats = (fit, lists)
        return self._fit_floats[1]

    def curve_one(
        self, fit: CompensationFit, temp: tuple[float, float], i0: list[int], bv: list[list[float]]
    ) -> tuple[tuple[float, float], tuple[float, float]] | None:
        """``curve_rows`` and ``curve_variance`` of one window with a temperature in both channels.

        Python floats, the products and sums of ``_curve_rows_known`` and ``_curve_variance_known``
        in numpy's order (a sum of at most five terms left to right, the quadratic form row by row,
        ``(b_i M_ij) b_j``), so the values are the same bit for bit. None where the fast case does
        not hold (a channel without a temperature, no curve): the general paths then.
        """
        if self.mode == "none" or i0[0] < 0 or i0[1] < 0:
            return None
        beta, minv, mbar, sbar, scale = self._floats(fit)
        g, v = [0.0, 0.0], [0.0, 0.0]
        last = self.q - 1
        for c in range(2):
            b, i, coef, m, mb = bv[c], i0[c], beta[c], minv[c], mbar[c]
            cols = [i, i + 1, i + 2, i + 3, last] if self.sun else [i, i + 1, i + 2, i + 3]
            out = 0.0
            for k in range(4):
                out += b[k] * coef[i + k]
            if self.sun:
                out += coef[-1] * b[4]
            t = temp[c]
            if t < self.t_min or t > self.t_max:
                out += self.slope_fe_floats[c] * (t - min(max(t, self.t_min), self.t_max))
            quad = 0.0
            for bi, ci in zip(b, cols, strict=True):
                row = m[ci]
                for bj, cj in zip(b, cols, strict=True):
                    quad += bi * row[cj] * bj
            lin = 0.0
            for bi, ci in zip(b, cols, strict=True):
                lin += bi * mb[ci]
            quad -= 2.0 * lin
            g[c] = out
            v[c] = scale[c] * max(quad + sbar[c], 0.0)
        return (g[0], g[1]), (v[0], v[1])

    def sun_weight(self, kappa: float, c: int) -> tuple[float, float]:
        """Return the sun prior of channel ``c`` as data: its weight ``sigma^2 / sd_gamma^2`` and mean (N).

        ``sigma^2 = kappa slope_sd^2`` is the noise model's per-sample variance (as for the slope prior).
        """
        mean_k, sd_k = self.sun_prior_k
        sigma2 = kappa * self.slope_sd**2
        return sigma2 / (sd_k * self.sun_slope[c]) ** 2, mean_k * self.sun_slope[c]

    # -- fitting --------------------------------------------------------------------------------
    def slope_weight(self, sigma2: np.ndarray) -> np.ndarray:
        """(2,) ``kappa`` (K) of the slope prior for per-sample noise variances ``sigma2`` (2,) N^2."""
        return np.asarray(sigma2, float).reshape(2) / self.slope_sd**2 * 1.0

    def fit(
        self,
        sums: FitSums,
        lam: np.ndarray | None = None,
        kappa: np.ndarray | None = None,
        long_run: np.ndarray | None = None,
    ) -> CompensationFit:
        """Fit both channels.

        ``lam`` (2,) reuses smoothing parameters (None: select them by REML/GCV); ``kappa`` (2,) K
        weighs the slope prior (``slope_weight`` of the noise model's variance; None: no prior).
        ``long_run`` (2,): the noise's long-run over its per-sample variance (the AR(1) factor; None:
        1). The sun prior is weighed on the long-run scale, the one the levels' share of the fit is
        read on (``SegmentChain.refresh``): with data that say nothing of the sun, ``g``'s variance
        there is the prior's, not the prior's times that factor. With ``sun_fit`` ``deck`` the sun
        term is one ``g`` of the deck for both channels, or out of the fit where its evidence does
        not carry it (``sun_evidence``, ``_sun_carried``).
        """
        q, n_seg = self.q, sums.n_segments
        beta = np.zeros((2, q))
        lams = np.full(2, np.inf)
        edf = np.zeros(2)
        minv = np.zeros((2, q, q))
        used = sums.ns > 0
        n_levels = int(np.count_nonzero(used))
        post = np.full((2, 2), np.nan)  # the sun's unconstrained posterior per channel: g mean, sd (K)
        systems: list[tuple[np.ndarray, np.ndarray] | None] = [None, None]
        for c in range(2):
            beta[c], lams[c], edf[c], minv[c], post[c], systems[c] = self._fit_channel(
                c, sums, n_levels, lam, kappa, long_run, self.sun
            )
        evidence = self.sun_evidence(post) if self.sun else _no_evidence()
        # per_bearing: each channel's own g (its truncated mode, ``_fit_channel``), always in
        deck = self.sun and self.sun_fit == "deck"
        average = self.sun and self.sun_fit == "average"
        carried = deck and self._sun_carried(evidence)
        if carried or (average and np.all(np.isfinite(evidence))):
            # one g of the deck for both channels: deck, its posterior's mode truncated at g >= 0
            # (NaN without one: each channel's own stays); average, the mixture's (its sd scaled)
            g, scale = self.averaged_sun(evidence) if average else (max(float(evidence[2]), 0.0), 1.0)
            if np.isfinite(g):
                for c, system in enumerate(systems):
                    if system is not None:
                        beta[c] = self._given_sun(c, *system, g)
                        minv[c, -1, :] *= scale
                        minv[c, :, -1] *= scale
        elif deck or average:  # not carried, or no evidence yet (no noise model to weigh it on)
            for c in range(2):
                beta[c], lams[c], edf[c], minv[c], _, _ = self._fit_channel(
                    c, sums, n_levels, lam, kappa, long_run, False
                )
        ws_all = np.where(used[:, None], sums.Ws, 1.0)
        level = (sums.sys - np.einsum("scq,cq->sc", sums.sbs, beta)) / ws_all
        level[~used] = 0.0
        dof = np.maximum(sums.n - n_levels - edf, 1.0)
        kap = np.zeros(2) if kappa is None else np.asarray(kappa, float).reshape(2)
        bbar = self._one * sums.sb / np.maximum(sums.W, 1e-300)[:, None]
        mbar = np.einsum("cij,cj->ci", minv, bbar)
        sbar = np.einsum("ci,ci->c", bbar, mbar)
        return CompensationFit(
            beta,
            lams,
            edf,
            level[:n_seg],
            dof,
            minv,
            sums.t_lo.copy(),
            sums.t_hi.copy(),
            kap,
            mbar,
            sbar,
            sums.n,
            bbar,
            self.sun,
            evidence,
        )

    def _fit_channel(
        self,
        c: int,
        sums: FitSums,
        n_levels: int,
        lam: np.ndarray | None,
        kappa: np.ndarray | None,
        long_run: np.ndarray | None,
        with_sun: bool,
    ) -> tuple[np.ndarray, float, float, np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray] | None]:
        """Fit channel ``c``: (beta (q,), lambda, edf, minv (q, q), the sun's posterior, the system).

        ``with_sun`` False fits the spline columns alone (the sun's coefficient, row and column 0).
        The sun's posterior is the unconstrained (untruncated) one of ``g``: mean and sd, K; NaN
        without a sun term, without data or without the noise model's weight. With the sun term the
        channel's system (matrix, right-hand side) is returned for ``_given_sun``, else None;
        ``beta`` is then the channel's own mode with ``g >= 0``.
        """
        q = self.q
        k = q if with_sun else self.q_spline
        beta, minv, lam_c, edf, post = np.zeros(q), np.zeros((q, q)), np.inf, 0.0, np.full(2, np.nan)
        used = sums.ns > 0
        ws = np.where(used, sums.Ws[:, c], 1.0)
        has_t = sums.W[c] > 0 and np.any(sums.sb[c] > 0)
        if self.mode == "none" or not has_t:
            return beta, lam_c, edf, minv, post, None
        sbs, sys = sums.sbs[:, c, :k], sums.sys[:, c]
        gw = sums.G[c][:k, :k] - (sbs.T / ws) @ sbs
        rw = sums.r[c][:k] - sbs.T @ (sys / ws)
        yyw = sums.yy[c] - float(np.sum(sys**2 / ws))
        gw = 0.5 * (gw + gw.T)
        kap = 0.0 if kappa is None else float(kappa[c])
        s_fe = self.slope_fe[c]
        gp = gw + kap * self.omega1[:k, :k]  # the slope prior, counted as data for lambda's choice
        rp = rw + kap * s_fe * self.e[:k]
        yyp = yyw + kap * s_fe**2 * self.span
        lr = 1.0 if long_run is None else float(long_run[c])
        if with_sun:  # the sun prior, as data (a tiny ridge without the noise model's variance)
            ks, g0 = self.sun_weight(kap, c) if kap > 0 else (1e-9 * (1.0 + gw[-1, -1]), 0.0)
            ks *= lr
            gp[-1, -1] += ks
            rp[-1] += ks * g0
            yyp += ks * g0**2
        if lam is not None and np.isfinite(lam[c]):
            lam_c = float(lam[c])
        elif self.mode == "fixed":
            lam_c = self.lam_fixed
        else:
            z = self._z if with_sun else self._z_spline
            omega = self.omega[:k, :k]
            lam_c = select_lambda(
                z.T @ gp @ z, z.T @ omega @ z, z.T @ rp, yyp, max(sums.n - n_levels, 2), self.mode
            )
        one = self._one[:k]
        cvec = one * sums.sb[c][:k] / np.sqrt(sums.W[c])
        mat = gp + lam_c * self.omega[:k, :k] + np.outer(cvec, cvec)  # + c c' fixes sb' beta = 0
        rhs = rp
        chol = linalg.cho_factor(mat, lower=True, check_finite=False)
        sol = linalg.cho_solve(chol, np.column_stack([rhs, gw, np.eye(k)]), check_finite=False)
        beta[:k] = sol[:, 0]
        if with_sun:
            beta = self._sun_heats_only(c, beta, mat, rhs)
            if kap > 0:  # the sun coefficient's posterior, on the long-run scale of its prior
                sd = np.sqrt(max(kap * self.slope_sd**2 * lr * float(sol[-1, -1]), 0.0))
                slope = float(self.sun_slope[c])
                post[:] = float(sol[-1, 0]) / slope, sd / abs(slope)
        edf = float(np.trace(sol[:, 1 : k + 1]))
        minv[:k, :k] = sol[:, k + 1 :]
        return beta, lam_c, edf, minv, post, ((mat, rhs) if with_sun else None)

    def sun_evidence(self, post: np.ndarray) -> np.ndarray:
        """Return the sun term's evidence (4,): ``ln B10``, ``ln B`` per bearing, ``g``'s mean and sd.

        ``post`` (2, 2): each channel's unconstrained posterior of ``g`` (mean, sd; K) under the
        prior ``N(m0, s0)``. Each channel's data alone say ``N(d_c, v_c)`` (the prior divided
        out). A vertical temperature difference of the deck is one ``g`` read through both
        bearings (independent fits): its posterior is the product of both with the prior.
        ``ln B10`` (Savage-Dickey: prior over posterior density at ``g = 0``, both of ``g >= 0``,
        the prior's truncation, each normalized on that half line; the term nests ``g = 0``, so
        the ratio is the Bayes factor against no term, Dickey 1971). The second value is the same
        for a ``g`` of each bearing's own (the sum of the two Savage-Dickey ratios): a pattern in
        one bearing that the other contradicts fits it better than one ``g`` of the deck. NaN
        where no channel has a posterior.
        """
        m0, s0 = self.sun_prior_k
        ok = np.isfinite(post).all(axis=1) & (post[:, 1] > 0)
        if not ok.any():
            return _no_evidence()
        prec, num = 1.0 / s0**2, m0 / s0**2
        for mu, sd in post[ok]:
            prec += max(1.0 / sd**2 - 1.0 / s0**2, 0.0)
            num += mu / sd**2 - m0 / s0**2
        mu, sd = num / prec, prec**-0.5
        separate = sum(_log_savage_dickey(m0, s0, m, v) for m, v in post[ok])
        return np.array([_log_savage_dickey(m0, s0, mu, sd), separate, mu, sd])

    @staticmethod
    def averaged_sun(evidence: np.ndarray) -> tuple[float, float]:
        """Return the deck's ``g`` (K) averaged over the explanations by evidence, and its sd's scale.

        Three explanations of the pattern that follows the sun, equally likely before the data: no
        sun term, one ``g`` of the deck, a ``g`` of each bearing's own (not the deck's sun). The
        deck's term is in with probability ``w = B_d / (1 + B_d + B_s)`` (``sun_evidence``'s Bayes
        factors); the average of ``g`` over them is ``w m`` (``m`` its posterior mode, ``g >= 0``)
        and its variance ``w (s^2 + m^2) - (w m)^2``. The scale multiplies the sun's row and column
        of the fit's inverse (its sd ``s`` under the term) so that its variance is the average's.
        """
        _, _, mean, sd = map(float, evidence)
        w = deck_sun_weight(evidence)
        m = max(mean, 0.0)
        var = w * (sd**2 + m**2) - (w * m) ** 2
        return w * m, (math.sqrt(max(var, 0.0)) / sd if sd > 0 else 1.0)

    def _sun_carried(self, evidence: np.ndarray) -> bool:
        """Return whether the sun term is in the fit: always (``sun_min_bf`` 0), or as its evidence says.

        One ``g`` for the deck must be at least ``sun_min_bf`` times as likely as no term and at
        least as likely as a ``g`` of each bearing's own (``sun_evidence``).
        """
        if self.sun_min_log_bf == -np.inf:
            return True
        log_bf, separate = float(evidence[0]), float(evidence[1])
        return log_bf >= self.sun_min_log_bf and log_bf >= separate - 1e-9

    def _sun_heats_only(self, c: int, b: np.ndarray, mat: np.ndarray, rhs: np.ndarray) -> np.ndarray:
        """Return channel ``c``'s coefficients ``b`` with ``g >= 0`` (the class docstring's truncation).

        Where ``b``'s sun coefficient means ``g < 0``, the mode of the truncated posterior lies on
        ``g = 0``: the other coefficients solve the system without the sun column.
        """
        return b if b[-1] * self.sun_slope[c] >= 0.0 else self._given_sun(c, mat, rhs, 0.0)

    def _given_sun(self, c: int, mat: np.ndarray, rhs: np.ndarray, g: float) -> np.ndarray:
        """Return channel ``c``'s coefficients with the sun's held at ``sun_slope_c g``, the rest refitted.

        The conditional mode of the Gaussian posterior: ``M_rr b_r = rhs_r - M_rs gamma``.
        """
        gamma = float(self.sun_slope[c]) * g
        out = np.zeros(len(rhs))
        out[:-1] = linalg.solve(
            mat[:-1, :-1], rhs[:-1] - mat[:-1, -1] * gamma, assume_a="pos", check_finite=False
        )
        out[-1] = gamma
        return out

    # -- evaluation -------------------------------------------------------------------------------
    def curve(self, fit: CompensationFit, temp_c: np.ndarray) -> np.ndarray:
        """Centred ``g(T)`` (n, 2) N at window temperatures (n, 2); 0 where T is unknown.

        Beyond the temperatures of the data the penalized curve itself continues: straight on (the
        curvature penalty) and bending toward the FE slope (the slope prior), so a trend made up
        by a few windows is not extrapolated while one that days of data show is. Beyond the knot
        range it continues with the FE slope.
        """
        t = np.asarray(temp_c, float).reshape(-1, 2)
        ok = np.isfinite(t)
        i0, bv = self.basis_rows(np.where(ok, t, np.nan))
        return self.curve_rows(fit, t, i0, bv)

    def curve_rows(
        self, fit: CompensationFit, temp_c: np.ndarray, i0: np.ndarray, bv: np.ndarray
    ) -> np.ndarray:
        """``curve`` for rows whose basis is already known: ``b(T)' beta`` (n, 2)."""
        t = np.asarray(temp_c, float).reshape(-1, 2)
        if self.mode == "none":
            return np.zeros(t.shape)
        if (i0 >= 0).all():
            return self._curve_rows_known(fit, t, i0, bv)
        return self._curve_rows_by_channel(fit, t, i0, bv)

    def _curve_rows_by_channel(
        self, fit: CompensationFit, t: np.ndarray, i0: np.ndarray, bv: np.ndarray
    ) -> np.ndarray:
        """``curve_rows``, channel by channel: rows without a temperature stay 0."""
        out = np.zeros(t.shape)
        for c in range(2):
            ok = i0[:, c] >= 0
            if not ok.any():
                continue
            coef = fit.beta[c][i0[ok, c][:, None] + np.arange(4)]
            out[ok, c] = np.sum(bv[ok, c, :4] * coef, axis=1)
            if self.sun:
                out[ok, c] += fit.beta[c, -1] * bv[ok, c, 4]
            beyond = ok & ((t[:, c] < self.t_min) | (t[:, c] > self.t_max))
            if beyond.any():
                tc = t[beyond, c]
                out[beyond, c] += self.slope_fe[c] * (tc - np.clip(tc, self.t_min, self.t_max))
        return out

    def curve_variance(self, fit: CompensationFit, i0: np.ndarray, bv: np.ndarray) -> np.ndarray:
        """Return the centred curve's own variance (n, 2) N^2 (Bayesian P-spline posterior), 0 without T.

        ``sigma^2 (b - bbar)' M^-1 (b - bbar)`` with ``bbar = sb / W`` (the curve is centred) and the
        ``sigma^2 = kappa * slope_sd^2`` that weighed the slope prior of this fit: small where days of
        data fix the curve, growing beyond the temperatures seen so far.
        """
        if self.mode == "none":
            return np.zeros(i0.shape, float)
        if (i0 >= 0).all():
            return self._curve_variance_known(fit, i0, bv)
        return self._curve_variance_by_channel(fit, i0, bv)

    def _curve_variance_by_channel(self, fit: CompensationFit, i0: np.ndarray, bv: np.ndarray) -> np.ndarray:
        """``curve_variance``, channel by channel: rows without a temperature stay 0."""
        out = np.zeros(i0.shape, float)
        for c in range(2):
            ok = i0[:, c] >= 0
            if not ok.any():
                continue
            cols = row_columns(i0[ok, c], self.width, self.q)  # (n, width)
            block = fit.minv[c][cols[:, :, None], cols[:, None, :]]  # (n, width, width)
            b = bv[ok, c]
            quad = np.einsum("ni,nij,nj->n", b, block, b) - 2.0 * np.sum(b * fit.mbar[c][cols], axis=1)
            out[ok, c] = fit.kappa[c] * self.slope_sd**2 * np.maximum(quad + fit.sbar[c], 0.0)
        return out

    def _curve_rows_known(
        self, fit: CompensationFit, t: np.ndarray, i0: np.ndarray, bv: np.ndarray
    ) -> np.ndarray:
        """``curve_rows`` where every row has a temperature in both channels: both channels at once.

        The same products and the same sums (each row's four terms in order) as
        ``_curve_rows_by_channel``, without its masks: a live window is one row.
        """
        chans = np.arange(2)[None, :, None]
        out = np.sum(bv[:, :, :4] * fit.beta[chans, i0[:, :, None] + np.arange(4)], axis=2)
        if self.sun:
            out += fit.beta[:, -1] * bv[:, :, 4]
        beyond = (t < self.t_min) | (t > self.t_max)
        if beyond.any():
            out[beyond] += (self.slope_fe * (t - np.clip(t, self.t_min, self.t_max)))[beyond]
        return out

    def _curve_variance_known(self, fit: CompensationFit, i0: np.ndarray, bv: np.ndarray) -> np.ndarray:
        """``curve_variance`` where every row has a temperature in both channels: both at once."""
        n, w = len(i0), self.width
        cols = row_columns(i0.ravel(), w, self.q).reshape(n, 2, w)
        chans = np.arange(2)[None, :, None]
        block = fit.minv[chans[..., None], cols[:, :, :, None], cols[:, :, None, :]]  # (n, 2, w, w)
        b = bv.reshape(n, 2, w)
        flat = b.reshape(2 * n, w)
        quad = np.einsum("ni,nij,nj->n", flat, block.reshape(2 * n, w, w), flat).reshape(n, 2)
        quad -= 2.0 * np.sum(b * fit.mbar[chans, cols], axis=2)
        return fit.kappa * self.slope_sd**2 * np.maximum(quad + fit.sbar, 0.0)

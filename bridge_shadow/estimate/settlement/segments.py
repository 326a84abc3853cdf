"""Settlement estimate over segments of constant settlement (Q = 0): information form, then a chain.

Between two detected events the settlement ``x_s`` is constant. The windows of segment ``s``,
compensated with the current curve (``z_w = y_w - u0 - g(T_w)``, N), are independent
measurements ``z_w = A x_s + e_w`` with ``cov(e_w) = diag(1/sqrt(m_w)) Rs diag(1/sqrt(m_w))``,
``Rs = C(n_s) o R1`` the per-sample covariance of a run of ``n_s`` windows (``NoiseModel``).
Their information is (``o`` is the Hadamard product, ``K = Rs^-1``)

    Lambda_s = sum_w A' S_w K S_w A = A' (K o M_s) A,         M_s,ij = sum_w sqrt(m_wi m_wj)
    eta_s    = sum_w A' S_w K S_w z_w = A' (K o Z_s) 1,      Z_s,ij = sum_w sqrt(m_wi m_wj) z_wj

(``S_w = diag(sqrt(m_w))``), so a segment is a measurement of ``x_s`` with mean
``x_d = Lambda_s^-1 eta_s`` and covariance ``D_s = Lambda_s^-1 + A^-1 diag(var_beta) A^-T`` (the
curve's own uncertainty, zero with one segment). ``M_s`` and ``Z_s`` come from ``FitSums``, so the
estimate is exact for the current curve and noise model whenever it is refreshed, however the
noise estimate moved since a window arrived.

The segments form a chain (filterpy ``KalmanFilter``, ``F = I``, ``H = I``):

    x_1 ~ N(0, Sigma_X)                       the prior
    x_s = x_{s-1} + j_s,  j_s ~ N(0, J)        an event opens the covariance by J (the prior's)
    x_d,s = x_s + d_s,    d_s ~ N(0, D_s)      the segment's windows

**The curve's error is common to all segments.** ``D_s`` above holds the curve's own
uncertainty ``var_beta`` (zero with one segment unless a sun term is fitted), but that error is
the *same* coefficient error ``dbeta_c ~ N(0, sigma_c^2 M_c^-1)`` in every segment: segment ``s``'s
measurement is ``x_d,s = x_s + H_s dbeta + w_s`` with ``H_s = A^-1 (x) v_s'`` (``v_s`` the
segment's mean basis row less the centring, ``CompensationFit.level_directions``). Counted
independently per segment, a step between records at different temperatures or under different
sun would be tested against the curve's error twice, although most of it cancels in the
difference (on sunny load-test days, steps stayed "unconfirmed" at change probabilities of
0.9-0.99). The chain is Schmidt's consider filter: ``dbeta`` is not estimated (the fit has used
what the data say about it), the posterior's cross-covariance ``C = cov(x - x_hat, dbeta)`` is
carried, and a segment's update is filterpy's ``update_correlated`` with ``M = C H_s'``:

    S = P + D_s + C H_s' + H_s C',   K = (P + C H_s') S^-1,   P <- P - K (P + C H_s')'
    C <- C - K (C + H_s Sigma_beta)

``P`` is then the true error covariance of the published estimate, and the change probability
below uses ``S`` (``test_estimate_segments`` checks both against the dense joint Gaussian).

With one segment this is exactly the paper's closed form
``Sigma' = (Sigma_X^-1 + sum_w A' R_w^-1 A)^-1``, ``mu' = Sigma' sum_w A' R_w^-1 (y_w - u0)`` on the
compensated windows (the centred curve drops out of the sum).

Between refreshes the current segment is updated window by window with the same formulas (its
``M``, ``Z`` kept as small arrays), so every window has its posterior at once.

**Provisional segments** (a gap in the data, or a held run that ended without confirmation) start
where the settlement *may* have changed: their jump is ``0`` with probability ``1 - pi`` and
``N(0, J)`` with probability ``pi`` (``change_prior_probability``). This is the two-model
(step / no step) case of an interacting-multiple-model filter, collapsed after each segment
(generalized pseudo-Bayes of order 1): with the previous posterior ``N(m, P)`` and the segment's
measurement ``x_d ~ N(x, D)``,

    L0 = N(x_d; m, S),   L1 = N(x_d; m, S + J)                the data's likelihood either way
    p  = pi L1 / (pi L1 + (1 - pi) L0)                           the change probability
    x_h, P_h = the Kalman update of N(m, P [+ J]) with x_d       h = 0 (no change), 1 (change)
    x = (1 - p) x_0 + p x_1
    P = (1 - p) P_0 + p P_1 + p (1 - p) (x_1 - x_0)(x_1 - x_0)'

so the posterior is honest in both outcomes: a real change of any size pulls ``p`` to 1 and the
estimate to the new state; no change keeps ``p`` small (the Occam factor ``sqrt(|S+J| / |S|)``)
and the estimate pooled, widened by what a change could still be. ``p`` is recomputed
at every refresh from the current curve and noise model. The shadow reports the change as
confirmed (an event) while ``p`` is at least ``change_confirm_probability``, and merges the
segment into the one before it (no change) once ``p`` is at most one minus that (``Shadow``).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from filterpy.kalman import KalmanFilter

from bridge_shadow.estimate.compensation.fit import CompensationFit
from bridge_shadow.estimate.compensation.noise import NoiseModel
from bridge_shadow.estimate.compensation.sums import FitSums
from bridge_shadow.estimate.small import Mat, Sym, Vec, congruence, inv_sym, mat_vec, quad_inv, sym_vec

__all__ = ["SegmentChain", "SegmentData", "SegmentSummary", "mixture_update"]

#: No correlation between a segment curve error and the prior (C_x = 0).
_NO_CROSS: Mat = (0.0, 0.0, 0.0, 0.0)


#: Windows that confirm a change where the data had stopped (across a gap, or right after a logger
#: outage inside a record: ``SegmentChain.confirms``) that no parked vehicle makes: it lowered the
#: reactions' sum (a vehicle only adds load) or raised it by more than the heaviest vehicle
#: (``traffic_vehicle_max_n``); so not ``event_confirm_windows``; two, because one window alone at
#: the end of the data or before a further step is what an outlier looks like.
GAP_LOWERING_WINDOWS = 2
#: A vehicle loads both girders (its share on each lies in [0, 1]: ``twin.traffic``'s lane
#: position, the real test car's +3 to +11 kN on both bearings), so a change that unloads one
#: bearing by more than this many of its standard deviations (the data estimates' on both sides of
#: the change, through ``A``) is none, whatever the sum: a south-down, north-up settlement moves
#: the bearings by -100 / +104 kN and their sum by +4 kN. One-sided 3 sd: 0.13 % of a vehicle
#: that loads one bearing alone reads as unloading it.
UNLOADED_SD = 3.0


@dataclass
class SegmentSummary:
    """What the data of one segment say and what the chain makes of it (m, m^2).

    Attributes:
        start_k: first window index of the segment.
        windows: windows in the segment.
        x_data: (2,) data-only estimate ``x_d`` (NaN without windows).
        d_cov: (2, 2) its covariance ``D``.
        x: (2,) chained posterior mean; P: (2, 2) its covariance.
        kind: ``start``, ``event``, ``gap``, ``held_run`` (an unconfirmed change), ``warmup`` or ``drift``.
        change_probability: probability that the settlement changed at the segment's start (1 for
            events and drift blocks, ``p`` for a provisional segment, NaN for the first segment).
        x_before: (2,) the chained posterior of the previous segment (NaN for the first);
        P_before: (2, 2) its covariance.
        change_chi2: the change from the previous segment's data estimate on the data alone
            (``SegmentChain.change_chi2``; NaN for the first or without data at either side).

    """

    start_k: int
    windows: int
    x_data: np.ndarray
    d_cov: np.ndarray
    x: np.ndarray
    P: np.ndarray
    kind: str = "start"
    change_probability: float = float("nan")
    x_before: np.ndarray = field(default_factory=lambda: np.full(2, np.nan))
    P_before: np.ndarray = field(default_factory=lambda: np.full((2, 2), np.nan))
    change_chi2: float = float("nan")


@dataclass(frozen=True)
class SegmentData:
    """One segment's measurement of its settlement (m, m^2), before the chain.

    Attributes:
        n: windows in the segment.
        x_d: (2,) data-only estimate ``Lambda^-1 eta`` (None without usable windows).
        lam_inv: (2, 2) its covariance from the windows' noise, ``Lambda^-1``.
        sky_cov: (2, 2) its further independent error (with a sun term: a misread sky), or None.
        v: (2, q) the curve coefficients' direction into the level, per channel
            (``CompensationFit.level_directions``; the curve's error is common to all segments).

    """

    n: int
    x_d: np.ndarray | None = None
    lam_inv: np.ndarray | None = None
    sky_cov: np.ndarray | None = None
    v: np.ndarray | None = None


def _log_normal(r: Vec, s: Sym) -> float:
    """``log N(r; 0, S)`` for a 2-vector ``r`` and a symmetric positive definite ``S`` (floats)."""
    det = s[0] * s[2] - s[1] * s[1]
    return -0.5 * (quad_inv(s, r) + math.log(det)) - math.log(2.0 * math.pi)


def mixture_update(
    m: Vec, p0: Sym, p1: Sym, prior: float, x_d: Vec | None, d: Sym | None, cx: Mat = _NO_CROSS
) -> tuple[Vec, Sym, float]:
    """Two-hypothesis update of ``N(m, p0)`` (no change) and ``N(m, p1)`` (change), collapsed.

    ``prior`` is the probability of a change before the data; ``x_d ~ N(x, d)`` is the segment's
    measurement (None: no data yet), whose curve error correlates with the prior's by ``cx``
    (``C H'``, the module docstring). Returns the collapsed mean, covariance and the posterior
    change probability (the module docstring's formulas, on floats).
    """
    x, cov, p, _ = _mixture(m, p0, p1, prior, x_d, d, cx)
    return x, cov, p


def _mixture(
    m: Vec, p0: Sym, p1: Sym, prior: float, x_d: Vec | None, d: Sym | None, cx: Mat
) -> tuple[Vec, Sym, float, Mat]:
    """``mixture_update``, and the collapsed gain ``(1 - p) K0 + p K1`` (zero without data)."""
    if x_d is None or d is None:
        widened = tuple(a + prior * (b - a) for a, b in zip(p0, p1, strict=True))
        return m, (widened[0], widened[1], widened[2]), prior, _NO_CROSS
    x0, c0, k0, s0 = _combine_gain(m, p0, cx, x_d, d)
    x1, c1, k1, s1 = _combine_gain(m, p1, cx, x_d, d)
    r = (x_d[0] - m[0], x_d[1] - m[1])
    log_odds = math.log(prior / (1.0 - prior)) + _log_normal(r, s1) - _log_normal(r, s0)
    p = 1.0 / (1.0 + math.exp(-log_odds)) if log_odds > -700.0 else 0.0
    q = 1.0 - p
    dx = (x1[0] - x0[0], x1[1] - x0[1])
    w = p * q
    x = (q * x0[0] + p * x1[0], q * x0[1] + p * x1[1])
    cov = (
        q * c0[0] + p * c1[0] + w * dx[0] * dx[0],
        q * c0[1] + p * c1[1] + w * dx[0] * dx[1],
        q * c0[2] + p * c1[2] + w * dx[1] * dx[1],
    )
    gain = (q * k0[0] + p * k1[0], q * k0[1] + p * k1[1], q * k0[2] + p * k1[2], q * k0[3] + p * k1[3])
    return x, cov, p, gain


def _segment_measurement(
    A: np.ndarray, K: np.ndarray, M: np.ndarray, Z: np.ndarray
) -> tuple[np.ndarray, np.ndarray] | None:
    """``(x_d, Lambda^-1)`` of a segment from ``K`` (2, 2), ``M`` (2, 2), ``Z`` (2, 2); None if empty."""
    if M[0, 0] <= 0 or M[1, 1] <= 0:
        return None
    info = A.T @ (K * M) @ A  # Lambda = A' (K o M) A
    eta = A.T @ (K * Z).sum(axis=1)  # eta = A' (K o Z) 1
    cov = np.linalg.inv(info)  # the covariance itself is needed, so an explicit inverse
    cov = 0.5 * (cov + cov.T)
    return cov @ eta, cov


@dataclass
class _Online:
    """The current segment's running sums between refreshes (Z compensated with the curve of its time).

    ``M = (M00, M01, M11)`` (symmetric), ``Z = (Z00, Z01, Z10, Z11)``, plain floats (hot path).
    """

    M: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    Z: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0, 0.0])
    n: int = 0

    @classmethod
    def from_arrays(cls, M: np.ndarray, Z: np.ndarray, n: int) -> _Online:
        return cls([float(M[0, 0]), float(M[0, 1]), float(M[1, 1])], [float(v) for v in np.ravel(Z)], int(n))

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        m = self.M
        return np.array([[m[0], m[1]], [m[1], m[2]]]), np.array(self.Z).reshape(2, 2)


def _sym(m: np.ndarray) -> Sym:
    return (float(m[0, 0]), float(0.5 * (m[0, 1] + m[1, 0])), float(m[1, 1]))


def _arr(m: Sym) -> np.ndarray:
    return np.array([[m[0], m[1]], [m[1], m[2]]])


def _mat(m: np.ndarray) -> Mat:
    return (float(m[0, 0]), float(m[0, 1]), float(m[1, 0]), float(m[1, 1]))


def _garr(m: Mat) -> np.ndarray:
    return np.array([[m[0], m[1]], [m[2], m[3]]])


class SegmentChain:
    """Posterior of the settlement, segment by segment (no process noise).

    Attributes:
        A: (2, 2) N/m; prior_cov: (2, 2) m^2 (``Sigma_X``); jump_cov: (2, 2) m^2 (``J``).
        starts: first window index of every segment (``starts[0]`` is the first window seen).
        kinds: per segment, ``start``, ``event``, ``gap``, ``held_run``, ``warmup`` or ``drift``.
        jumps: per segment, the covariance it certainly opens (m^2): ``J`` for an event, ``Q dt``
            for a drift block, 0 (or ``Q dt``) for a provisional segment.
        change_prior: per segment, the prior probability ``pi`` of its uncertain jump ``J`` (0 for
            none, which is every segment that is not provisional).
        summaries: per segment, the last refresh's ``SegmentSummary``.
        n_updates: windows used.
        x: (2,) m and P: (2, 2) m^2, the current posterior (properties over float state).

    """

    def __init__(
        self, A: np.ndarray, prior_cov: np.ndarray, jump_cov: np.ndarray, vehicle_max_n: float = math.inf
    ) -> None:
        self.A = np.asarray(A, float).reshape(2, 2)
        self.vehicle_max_n = float(vehicle_max_n)
        self.a_inv = np.linalg.inv(self.A)
        self.prior_cov = np.asarray(prior_cov, float).reshape(2, 2)
        self.jump_cov = np.asarray(jump_cov, float).reshape(2, 2)
        self.starts: list[int] = []
        self.kinds: list[str] = []
        self.jumps: list[np.ndarray] = []  # covariance opened for certain at each segment start (m^2)
        self.change_prior: list[float] = []  # probability of a further jump J (provisional segments)
        self.summaries: list[SegmentSummary] = []
        self.outage_starts: set[int] = set()  # first windows after a logger outage (``mark_outage``)
        self.n_updates = 0
        self._atf = (float(self.A[0, 0]), float(self.A[1, 0]), float(self.A[0, 1]), float(self.A[1, 1]))
        self._m0f: Vec = (0.0, 0.0)  # prior of the current segment (no change, for a provisional one)
        self._p0f: Sym = _sym(self.prior_cov)
        self._p1f: Sym = self._p0f  # its prior covariance after a change (provisional segment)
        self._pi = 0.0  # prior change probability of the current segment (0: not provisional)
        self._p = float("nan")  # posterior change probability of the current segment
        self._beta_covf: Sym = (0.0, 0.0, 0.0)  # curve term of the current segment (x space)
        self._cxf: Mat = _NO_CROSS  # its curve error's covariance with the prior's (C H')
        self._before: tuple[Vec, Sym] = ((math.nan, math.nan), (math.nan, math.nan, math.nan))
        self._noise: NoiseModel | None = None
        self._online = _Online()
        self._x: Vec = self._m0f
        self._P: Sym = self._p0f

    @property
    def x(self) -> np.ndarray:
        """Posterior mean (2,) m."""
        return np.array(self._x)

    @property
    def P(self) -> np.ndarray:
        """Posterior covariance (2, 2) m^2."""
        return _arr(self._P)

    @property
    def segment(self) -> int:
        """Index of the current segment (0 before the first window)."""
        return max(len(self.starts) - 1, 0)

    @property
    def provisional(self) -> bool:
        """Whether the current segment's start is an unconfirmed change (a gap or a held run)."""
        return 0.0 < self._pi < 1.0

    @property
    def change_probability(self) -> float:
        """Posterior probability that the settlement changed at the current segment's start.

        1 after a confirmed event or a drift block, ``p`` for a provisional segment, NaN for the
        first segment.
        """
        if not self.starts or len(self.starts) == 1:
            return float("nan")
        return self._p if self.provisional else 1.0

    def level_change(self) -> Vec:
        """Return the current level less the one before the current segment opened (m; NaN for the first)."""
        (b0, b1), _ = self._before
        return (self._x[0] - b0, self._x[1] - b1)

    @property
    def current_windows(self) -> int:
        """Windows in the current segment (online count)."""
        return self._online.n

    # -- events ---------------------------------------------------------------------------------
    def start(self, k: int) -> None:
        """Open the first segment at window ``k`` (once)."""
        if not self.starts:
            self.starts.append(int(k))
            self.kinds.append("start")
            self.jumps.append(np.zeros((2, 2)))
            self.change_prior.append(0.0)

    def open_segment(
        self, k: int, jump_cov: np.ndarray | None = None, kind: str = "event", change_prior: float = 0.0
    ) -> None:
        """Open a new segment from window ``k``.

        Its prior is the last posterior plus ``J`` (an event), plus ``jump_cov`` (a random-walk
        block), or, with ``0 < change_prior < 1`` (a provisional segment: ``gap``, ``held_run``, ``warmup``),
        plus ``jump_cov`` (default 0) for certain and ``J`` with probability ``change_prior``.
        """
        provisional = 0.0 < change_prior < 1.0
        if jump_cov is None:
            jump = np.zeros((2, 2)) if provisional else self.jump_cov
        else:
            jump = np.asarray(jump_cov, float).reshape(2, 2)
        self.jumps.append(jump)
        self.kinds.append(kind)
        self.change_prior.append(float(change_prior) if provisional else 0.0)
        j = _sym(jump)
        jj = _sym(self.jump_cov)
        self._before = (self._x, self._P)
        self._m0f = self._x
        self._p0f = (self._P[0] + j[0], self._P[1] + j[1], self._P[2] + j[2])
        self._p1f = (self._p0f[0] + jj[0], self._p0f[1] + jj[1], self._p0f[2] + jj[2])
        self._pi = self.change_prior[-1]
        self._beta_covf, self._cxf = (0.0, 0.0, 0.0), _NO_CROSS
        self.starts.append(int(k))
        self._online = _Online()
        self._update_current()
        self._prune_outages()

    def move_start(self, k: int) -> None:
        """Let the current segment, still without a window, begin at window ``k`` (its first left out)."""
        if self._online.n or not self.starts or k < self.starts[-1]:
            raise ValueError("only a segment without windows moves its start, and only later")
        self.starts[-1] = int(k)

    def _prune_outages(self) -> None:
        """Keep the outage marks a segment may still start at (the provisional ones' and later)."""
        if not self.outage_starts:
            return
        open_starts = [k for k, p in zip(self.starts, self.change_prior, strict=True) if 0.0 < p < 1.0]
        floor = min([self.starts[-1], *open_starts])
        self.outage_starts = {k for k in self.outage_starts if k >= floor}

    def segment_probability(self, s: int) -> tuple[float, int]:
        """Change probability at segment ``s``'s start, and its windows (the current one online)."""
        if s == len(self.starts) - 1:
            return self.change_probability, self._online.n
        if 0 < s < len(self.summaries):
            return self.summaries[s].change_probability, self.summaries[s].windows
        return float("nan"), 0

    def confirms(self, s: int, probability: float, windows: int, min_chi2: float = 0.0) -> bool:
        """Return whether segment ``s``'s change is confirmed (the one rule of every confirmation).

        Its change probability at least ``probability``, its size significant on the data
        (``change_chi2`` at least ``min_chi2``), and at least ``windows`` windows that stayed with
        it (``windows_changed``); ``GAP_LOWERING_WINDOWS`` for a change no vehicle makes where the
        data had stopped (``_no_vehicle_where_data_stopped``).
        """
        p, _ = self.segment_probability(s)
        if p < probability or (min_chi2 > 0.0 and self.change_chi2(s) < min_chi2):
            return False  # (NaN, not refreshed since the segment opened: not known yet, not held against it)
        need = min(windows, GAP_LOWERING_WINDOWS) if self._no_vehicle_where_data_stopped(s) else windows
        return self.windows_changed(s, need) >= need

    def change_chi2(self, s: int) -> float:
        """Chi-square of segment ``s``'s change on the data alone, as of the last refresh (else NaN).

        Its data estimate less the previous segment's, against the covariance of that difference
        (``_difference_chi2``: both segments' noise and the curve's error as far as the two read it
        differently; not the model's uncertainty of a change read through ``A``, which scales a
        change and cannot make one).
        """
        if 0 < s < len(self.summaries) and self.summaries[s].start_k == self.starts[s]:
            return float(self.summaries[s].change_chi2)
        return float("nan")

    def mark_outage(self, k: int) -> None:
        """Note that window ``k`` is the first usable one after a logger outage shorter than a gap."""
        self.outage_starts.add(int(k))

    def _no_vehicle_where_data_stopped(self, s: int) -> bool:
        """Return whether segment ``s`` starts where the data had stopped with a change no vehicle makes.

        The windows ``event_confirm_windows`` asks for are there to tell a change from a load that
        stays for minutes (a parked test car); a vehicle only adds load (``inputs.traffic``), so a
        change that takes load off the bearings is none, nor one that unloads one bearing
        (``UNLOADED_SD``: a vehicle loads both girders), and so is one that adds more to their sum
        than the heaviest vehicle (``vehicle_max_n``, the traffic screen's own limit of a vehicle:
        ``traffic_vehicle_max_n``). Only where the data had stopped: across a
        gap, or at the first usable window after a logger outage inside a record (``mark_outage``:
        windows without any force data). There the segment's start is the data's, and the change
        happened while nothing was recorded; inside continuous data a short state can be the
        detector's own reading of a step under the test car (split in two).
        """
        if not 0 < s < len(self.summaries):
            return False
        if self.kinds[s] != "gap" and self.starts[s] not in self.outage_starts:
            return False
        sm = self.summaries[s]
        d = self.A @ (sm.x_data - sm.x_before)
        if not np.all(np.isfinite(d)):
            return False
        if not 0.0 <= float(d.sum()) <= self.vehicle_max_n:
            return True
        cov = self.A @ (sm.d_cov + sm.P_before) @ self.A.T
        sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
        return bool(np.all(np.isfinite(sd)) and np.any(d < -UNLOADED_SD * sd))

    def windows_changed(self, s: int, enough: int | None = None) -> int:
        """Windows from segment ``s``'s start on that stayed away from the state before it.

        Its own windows, and those of the segments after it (up to the next gap) whose level lies
        within half of ``s``'s change of ``s``'s own state along that change: closer to the step
        than to no change (the detector's rule for a run that has not come back), and closer to it
        than to a second step of its size (the windows of a much larger change after it say
        nothing of a small one's). Counting stops once it reaches ``enough``. A change confirmed only
        by its own windows waited for a state that a further change ended after two or three (a
        lowering at a record's first minutes, a further one after the test car's).
        """
        if not 0 < s < len(self.starts):
            return 0
        current = len(self.starts) - 1
        if s == current:
            return self._online.n
        if s >= len(self.summaries):
            return 0
        sm = self.summaries[s]
        d = sm.x_data - sm.x_before
        dd = float(d @ d)
        n = sm.windows
        if not np.isfinite(dd) or dd <= 0.0:
            return n
        for t in range(s + 1, current + 1):
            if self.kinds[t] == "gap" or (enough is not None and n >= enough):
                break
            if t == current:
                x_t, n_t = np.array(self._x), self._online.n
            elif t < len(self.summaries):
                x_t, n_t = self.summaries[t].x, self.summaries[t].windows
            else:
                break
            if not 0.5 * dd <= float((x_t - sm.x_before) @ d) <= 1.5 * dd:
                break
            n += n_t
        return n

    def remove_segment(self, s: int) -> None:
        """Drop the start of segment ``s`` (its windows belong to ``s - 1`` now); refresh after it."""
        if not 0 < s < len(self.starts):
            return
        for seq in (self.starts, self.kinds, self.jumps, self.change_prior):
            del seq[s]
        if s < len(self.summaries):
            del self.summaries[s]
        if s == len(self.starts):  # it was the current segment: the previous one goes on
            self._pi = self.change_prior[-1]

    def restart_current(self) -> None:
        """Forget the current segment's windows online (they are re-added one by one)."""
        self.n_updates -= self._online.n
        self._online = _Online()
        self._update_current()

    # -- windows --------------------------------------------------------------------------------
    def predict_floats(self) -> tuple[Vec, Sym]:
        """Return the prediction for the next window as floats (the settlement does not move)."""
        return self._x, self._P

    def accept(self, samples: np.ndarray, z_n: np.ndarray) -> None:
        """Add one compensated window ``z_n`` (2,) N over ``samples`` (2,) to the current segment."""
        m0, m1 = float(samples[0]), float(samples[1])
        z0, z1 = float(z_n[0]), float(z_n[1])
        p = math.sqrt(m0 * m1)
        on = self._online
        M, Z = on.M, on.Z
        M[0] += m0
        M[1] += p
        M[2] += m1
        Z[0] += m0 * z0
        Z[1] += p * z1
        Z[2] += p * z0
        Z[3] += m1 * z1
        on.n += 1
        self.n_updates += 1
        self._update_current()

    def _current_data(self) -> tuple[Vec, Sym] | None:
        """``(x_d, D)`` of the current segment from its running sums (None without usable windows)."""
        on = self._online
        if on.n == 0 or on.M[0] <= 0.0 or on.M[2] <= 0.0:
            return None
        if self._noise is None:
            raise RuntimeError("refresh the chain with a noise model before adding windows")
        k00, k01, k11 = inv_sym(self._noise.run_cov_floats(on.n))  # K = Rs^-1
        M, Z = on.M, on.Z
        at = self._atf
        info = congruence(at, (k00 * M[0], k01 * M[1], k11 * M[2]))  # Lambda = A' (K o M) A
        eta = mat_vec(at, (k00 * Z[0] + k01 * Z[1], k01 * Z[2] + k11 * Z[3]))  # eta = A' (K o Z) 1
        lam_inv = inv_sym(info)
        x_d = sym_vec(lam_inv, eta)
        bc = self._beta_covf
        return x_d, (lam_inv[0] + bc[0], lam_inv[1] + bc[1], lam_inv[2] + bc[2])

    def _update_current(self) -> None:
        """Update the current segment's posterior from its running sums (the module's formulas, on floats)."""
        data = self._current_data()
        if 0.0 < self._pi < 1.0:
            x_d, d = data if data is not None else (None, None)
            self._x, self._P, self._p = mixture_update(
                self._m0f, self._p0f, self._p1f, self._pi, x_d, d, self._cxf
            )
        elif data is None:
            self._x, self._P = self._m0f, self._p0f
        else:
            self._x, self._P = _combine_f(self._m0f, self._p0f, *data, self._cxf)

    def current_measurement(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Return the current segment's ``x_d`` (2,) m and ``D`` (2, 2) m^2, and the previous posterior.

        The previous segment's chained posterior (before this segment's jump): mean (2,) m and
        covariance (2, 2) m^2 (NaN for the first segment). ``x_d`` and ``D`` are NaN without data.
        """
        data = self._current_data()
        if data is None:
            x_d, d = np.full(2, np.nan), np.full((2, 2), np.nan)
        else:
            x_d, d = np.array(data[0]), _arr(data[1])
        return x_d, d, np.array(self._before[0]), _arr(self._before[1])

    # -- exact recomputation ----------------------------------------------------------------------
    def use_noise(self, noise: NoiseModel) -> None:
        """Take ``noise`` for the windows to come (as ``refresh`` does, without recomputing)."""
        self._noise = noise

    def refresh(self, sums: FitSums, fit: CompensationFit, noise: NoiseModel) -> None:
        """Recompute every segment and the chain from the sums, the curve and the noise model."""
        self._noise = noise
        sigma2 = np.diag(noise.long_run_cov())
        data = [self._segment_data(sums, fit, noise, s) for s in range(len(self.starts))]
        self.run_chain(data, sigma2[:, None, None] * fit.minv)
        n_seg = len(self.starts)
        if n_seg:
            n_last = int(sums.ns[n_seg - 1]) if n_seg - 1 < sums.n_segments else 0
            self._online = (
                _Online.from_arrays(*self._sums_mz(sums, fit, n_seg - 1), n_last) if n_last else _Online()
            )
        self.n_updates = int(sums.n)

    def _segment_data(self, sums: FitSums, fit: CompensationFit, noise: NoiseModel, s: int) -> SegmentData:
        """Return what segment ``s``'s windows say, compensated with ``fit`` (``SegmentData``)."""
        n_s = int(sums.ns[s]) if s < sums.n_segments else 0
        if not n_s:
            return SegmentData(0)
        M, Z = self._sums_mz(sums, fit, s)
        meas = _segment_measurement(self.A, np.linalg.inv(noise.run_cov(n_s)), M, Z)
        if meas is None:
            return SegmentData(n_s)
        sky = None
        if fit.sun:  # a misread sky moves the segment's level in both channels together
            f = fit.beta[:, -1] * sums.Ssv[s] / np.maximum(sums.Ws[s], 1e-300)
            sky = self.a_inv @ np.outer(f, f) @ self.a_inv.T
        return SegmentData(n_s, meas[0], meas[1], sky, fit.level_directions(sums, s))

    def run_chain(self, data: list[SegmentData], curve_cov: np.ndarray) -> None:
        """Run the chain over the segments' ``data`` (one per segment; the module docstring).

        ``curve_cov`` (2, q, q): the covariance of the curve's coefficients per channel,
        ``sigma_c^2 M_c^-1``. Their error is common to every segment's level: the chain carries
        the posterior's cross-covariance ``C`` (2, 2, q) with it (Schmidt's consider filter).
        """
        kf = KalmanFilter(dim_x=2, dim_z=2)
        kf.x = np.zeros((2, 1))
        kf.P = self.prior_cov.copy()
        kf.F = np.eye(2)
        kf.H = np.eye(2)
        cross = np.zeros((2, curve_cov.shape[0], curve_cov.shape[1]))
        self.summaries = []
        n_seg = len(self.starts)
        before: SegmentData | None = None  # the previous segment's data
        for s in range(n_seg):
            x_before, p_before = kf.x[:, 0].copy(), kf.P.copy()  # segment s - 1's posterior
            if s > 0:
                kf.predict(Q=self.jumps[s])  # x_s = x_{s-1} + j_s
            pi = self.change_prior[s]
            mixed = 0.0 < pi < 1.0
            m0, p0 = (float(kf.x[0, 0]), float(kf.x[1, 0])), _sym(kf.P)
            p1 = _sym(kf.P + self.jump_cov) if mixed else p0
            if s == n_seg - 1:
                self._m0f, self._p0f, self._p1f, self._pi = m0, p0, p1, pi
                self._beta_covf, self._cxf = (0.0, 0.0, 0.0), _NO_CROSS
                if s > 0:
                    self._before = ((float(x_before[0]), float(x_before[1])), _sym(p_before))
            seg = data[s]
            x_d, d_cov = np.full(2, np.nan), np.full((2, 2), np.nan)
            if seg.x_d is not None:
                x_d = seg.x_d
                v = seg.v  # H = A^-1 (x) v: x_d's curve error is H dbeta
                v_sig = np.einsum("ci,cij->cj", v, curve_cov)  # (2, q) v_c' Sigma_c
                hsig = self.a_inv[:, :, None] * v_sig[None]  # H Sigma (2, 2, q)
                beta_cov = self.a_inv @ np.diag((v_sig * v).sum(axis=1)) @ self.a_inv.T  # H Sigma H'
                cx = np.einsum("ick,ck->ic", cross, v) @ self.a_inv.T  # C H'
                if seg.sky_cov is not None:
                    beta_cov = beta_cov + seg.sky_cov
                d_cov = seg.lam_inv + beta_cov
                if s == n_seg - 1:
                    self._beta_covf, self._cxf = _sym(beta_cov), _mat(cx)
            prob = float("nan") if s == 0 else 1.0
            if mixed:
                xd = None if seg.x_d is None else (float(x_d[0]), float(x_d[1]))
                dm = None if seg.x_d is None else _sym(d_cov)
                cxm = _NO_CROSS if seg.x_d is None else _mat(cx)
                x_m, p_m, prob, gain = _mixture(m0, p0, p1, pi, xd, dm, cxm)
                kf.x = np.array([[x_m[0]], [x_m[1]]])
                kf.P = _arr(p_m)
                if seg.x_d is not None:
                    cross = cross - np.einsum("ij,jck->ick", _garr(gain), cross + hsig)
            elif seg.x_d is not None:
                # z as a column (filterpy 2.0.0 shape bug); with a curve error correlated with the
                # prior's, filterpy's update for correlated noise (M = C H'; its P is not Joseph form)
                if np.any(cx):
                    kf.M = cx
                    kf.update_correlated(x_d.reshape(2, 1), R=d_cov, H=np.eye(2))
                else:
                    kf.update(x_d.reshape(2, 1), R=d_cov, H=np.eye(2))
                kf.P = 0.5 * (kf.P + kf.P.T)
                cross = cross - np.einsum("ij,jck->ick", kf.K, cross + hsig)
            if s == 0:
                x_before, p_before = np.full(2, np.nan), np.full((2, 2), np.nan)
            chi2 = self._difference_chi2(before, seg, curve_cov) if s > 0 else float("nan")
            before = seg
            self.summaries.append(
                SegmentSummary(
                    self.starts[s],
                    seg.n,
                    x_d,
                    d_cov,
                    kf.x[:, 0].copy(),
                    kf.P.copy(),
                    self.kinds[s],
                    prob,
                    x_before,
                    p_before,
                    chi2,
                )
            )
        if n_seg:
            self._x, self._P = (float(kf.x[0, 0]), float(kf.x[1, 0])), _sym(kf.P)
            self._p = self.summaries[-1].change_probability

    def _difference_chi2(self, a: SegmentData | None, b: SegmentData, curve_cov: np.ndarray) -> float:
        """Chi-square of ``b``'s data estimate less ``a``'s against the covariance of that difference.

        Both segments' noise (``Lambda^-1``, and a misread sky's), and the curve's error through the
        difference of their level directions, ``A^-1 (v_b - v_a) Sigma (v_b - v_a)' A^-T`` per
        channel: an error of the curve common to both cancels as far as the two segments read it
        alike (the same temperatures, the same sky). NaN without data at either side.
        """
        if a is None or a.x_d is None or b.x_d is None or a.lam_inv is None or b.lam_inv is None:
            return float("nan")
        cov = np.asarray(a.lam_inv, float) + np.asarray(b.lam_inv, float)
        for extra in (a.sky_cov, b.sky_cov):
            if extra is not None:
                cov = cov + extra
        if a.v is not None and b.v is not None:
            dv = np.asarray(b.v, float) - np.asarray(a.v, float)
            var = np.einsum("ci,cij,cj->c", dv, curve_cov, dv)
            cov = cov + self.a_inv @ np.diag(var) @ self.a_inv.T
        d = np.asarray(b.x_d, float) - np.asarray(a.x_d, float)
        if not (np.all(np.isfinite(d)) and np.all(np.isfinite(cov))):
            return float("nan")
        return float(d @ np.linalg.solve(cov, d))

    @staticmethod
    def _sums_mz(sums: FitSums, fit: CompensationFit, s: int) -> tuple[np.ndarray, np.ndarray]:
        """``M_s`` and ``Z_s`` (2, 2) of segment ``s`` with the curve ``fit`` (z = y - g~(T))."""
        if s >= sums.n_segments:
            return np.zeros((2, 2)), np.zeros((2, 2))
        b0, b1 = fit.beta
        M = np.array([[sums.Ws[s, 0], sums.X1s[s]], [sums.X1s[s], sums.Ws[s, 1]]])
        Z = np.array(
            [
                [sums.sys[s, 0] - sums.sbs[s, 0] @ b0, sums.Xy1s[s] - sums.Xb1s[s] @ b1],
                [sums.Xy0s[s] - sums.Xb0s[s] @ b0, sums.sys[s, 1] - sums.sbs[s, 1] @ b1],
            ]
        )
        return M, Z

    def posterior(self) -> tuple[np.ndarray, np.ndarray]:
        """Posterior mean (2,) m and covariance (2, 2) m^2 of the current segment."""
        return self.x, self.P

    # -- state ----------------------------------------------------------------------------------
    def state_dict(self) -> dict[str, Any]:
        """Plain-data state (the summaries are recomputed at the next refresh)."""
        sm = self.summaries
        return {
            "starts": np.asarray(self.starts, np.int64),
            "kinds": json.dumps(self.kinds),
            "jumps": np.asarray(self.jumps, float).reshape(-1, 2, 2),
            "change_prior": np.asarray(self.change_prior, float),
            "n_updates": self.n_updates,
            "outage_starts": np.array(sorted(self.outage_starts), np.int64),
            "m0": np.array(self._m0f),
            "p0": _arr(self._p0f),
            "p1": _arr(self._p1f),
            "pi": self._pi,
            "p": self._p,
            "beta_cov": _arr(self._beta_covf),
            "cross": _garr(self._cxf),
            "before_x": np.array(self._before[0]),
            "before_P": _arr(self._before[1]),
            "online_M": self._online.arrays()[0],
            "online_Z": self._online.arrays()[1],
            "online_n": self._online.n,
            "x": self.x,
            "P": self.P,
            "summaries": {
                "start_k": np.array([s.start_k for s in sm], np.int64),
                "windows": np.array([s.windows for s in sm], np.int64),
                "x_data": np.array([s.x_data for s in sm]).reshape(-1, 2),
                "d_cov": np.array([s.d_cov for s in sm]).reshape(-1, 2, 2),
                "x": np.array([s.x for s in sm]).reshape(-1, 2),
                "P": np.array([s.P for s in sm]).reshape(-1, 2, 2),
                "kind": json.dumps([s.kind for s in sm]),
                "change_chi2": np.array([s.change_chi2 for s in sm], float),
                "change_probability": np.array([s.change_probability for s in sm], float),
                "x_before": np.array([s.x_before for s in sm]).reshape(-1, 2),
                "P_before": np.array([s.P_before for s in sm]).reshape(-1, 2, 2),
            },
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore the state."""
        self.starts = [int(k) for k in np.asarray(state["starts"]).ravel()]
        self.kinds = list(json.loads(str(state["kinds"])))
        self.jumps = list(np.asarray(state["jumps"], float).reshape(-1, 2, 2))
        self.change_prior = [float(p) for p in np.asarray(state["change_prior"], float).ravel()]
        self.n_updates = int(state["n_updates"])
        # checkpoints written before logger outages were marked have none
        marks = state["outage_starts"] if "outage_starts" in state else []
        self.outage_starts = {int(k) for k in np.asarray(marks, np.int64).ravel()}
        m0 = np.asarray(state["m0"], float).reshape(2)
        self._m0f = (float(m0[0]), float(m0[1]))
        self._p0f = _sym(np.asarray(state["p0"], float).reshape(2, 2))
        self._p1f = _sym(np.asarray(state["p1"], float).reshape(2, 2))
        self._pi = float(state["pi"])
        self._p = float(state["p"])
        self._beta_covf = _sym(np.asarray(state["beta_cov"], float).reshape(2, 2))
        self._cxf = _mat(np.asarray(state["cross"], float).reshape(2, 2)) if "cross" in state else _NO_CROSS
        bx = np.asarray(state["before_x"], float).reshape(2)
        before_p = _sym(np.asarray(state["before_P"], float).reshape(2, 2))
        self._before = ((float(bx[0]), float(bx[1])), before_p)
        self._online = _Online.from_arrays(
            np.asarray(state["online_M"], float).reshape(2, 2),
            np.asarray(state["online_Z"], float).reshape(2, 2),
            int(state["online_n"]),
        )
        x = np.asarray(state["x"], float).reshape(2)
        self._x = (float(x[0]), float(x[1]))
        self._P = _sym(np.asarray(state["P"], float).reshape(2, 2))
        sm = state["summaries"]
        kinds = json.loads(str(sm["kind"]))
        # checkpoints written before the change's chi-square was kept: unknown (NaN) until a refresh
        chi2s = np.asarray(sm["change_chi2"] if "change_chi2" in sm else np.full(len(kinds), np.nan), float)
        chi2s = chi2s.ravel()
        self.summaries = [
            SegmentSummary(int(k), int(n), xd, d, x, P, kd, float(pr), xb, pb, float(c2))
            for k, n, xd, d, x, P, kd, pr, xb, pb, c2 in zip(
                np.asarray(sm["start_k"]).ravel(),
                np.asarray(sm["windows"]).ravel(),
                np.asarray(sm["x_data"], float).reshape(-1, 2),
                np.asarray(sm["d_cov"], float).reshape(-1, 2, 2),
                np.asarray(sm["x"], float).reshape(-1, 2),
                np.asarray(sm["P"], float).reshape(-1, 2, 2),
                kinds,
                np.asarray(sm["change_probability"], float).ravel(),
                np.asarray(sm["x_before"], float).reshape(-1, 2),
                np.asarray(sm["P_before"], float).reshape(-1, 2, 2),
                chi2s,
                strict=True,
            )
        ]


def _combine_f(m0: Vec, p0: Sym, x_d: Vec, d: Sym, cx: Mat = _NO_CROSS) -> tuple[Vec, Sym]:
    """Kalman update of ``N(m0, p0)`` with ``x_d ~ N(x, d)`` correlated by ``cx`` (floats)."""
    x, cov, _, _ = _combine_gain(m0, p0, cx, x_d, d)
    return x, cov


def _combine_gain(m0: Vec, p0: Sym, cx: Mat, x_d: Vec, d: Sym) -> tuple[Vec, Sym, Mat, Sym]:
    """Return ``x``, ``P``, the gain ``K`` and the innovation covariance ``S`` of one update (floats).

    ``S = P0 + D + C_x + C_x'``, ``G = P0 + C_x``, ``K = G S^-1``, ``x = m0 + K (x_d - m0)``,
    ``P = P0 - G S^-1 G'`` (filterpy's ``update_correlated`` with ``H = I``, ``M = C_x``).
    """
    a, b, dd = p0
    c0, c1, c2, c3 = cx
    s = (a + d[0] + 2.0 * c0, b + d[1] + c1 + c2, dd + d[2] + 2.0 * c3)
    sa, sb, sd = inv_sym(s)
    g = (a + c0, b + c1, b + c2, dd + c3)
    k = (g[0] * sa + g[1] * sb, g[0] * sb + g[1] * sd, g[2] * sa + g[3] * sb, g[2] * sb + g[3] * sd)
    r0, r1 = x_d[0] - m0[0], x_d[1] - m0[1]
    x = (m0[0] + k[0] * r0 + k[1] * r1, m0[1] + k[2] * r0 + k[3] * r1)
    q = congruence(g, (sa, sb, sd))
    return x, (a - q[0], b - q[1], dd - q[2]), k, s

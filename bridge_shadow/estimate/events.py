"""Settlement-event detector: a generalized likelihood ratio (GLR) test for a step in the innovations.

Each window brings an innovation ``v = z - A x`` (N, 2) against the current settlement estimate,
with its single-window covariance ``S1 = R1 / m + A P A'`` (``NoiseModel.window_cov`` plus the
estimate's own uncertainty). Without a change, ``v' S1^-1 v`` is chi-square with two degrees of
freedom.

1. **Trigger.** A window with ``v' S1^-1 v > h_trigger`` (``event_trigger_probability``) starts a
   *pending* run; pending windows are held (not yet in the fit, the noise model or the output).
2. **GLR with change-time estimation.** For each candidate start ``j`` of the pending run of ``n``
   windows, the sum ``s_j = sum_{i >= j} v_i`` of its ``n_j`` windows has, without a change, the
   covariance ``V_j = F(n_j) o R1 / m + n_j^2 A P A'``, with ``F(n) = n f(n)`` the AR(1) variance of a
   sum of ``n`` windows (``noise.ar1_factor``: a slow wander of autocorrelated noise is not a step).
   The test statistic is ``T_j = s_j' V_j^-1 s_j`` and the step estimate ``s_j / n_j``.
3. **Decision** after each pending window:

   - *event*: the best candidate ``j*`` (largest ``T_j`` among those whose windows scatter around
     the step like noise, ``sum (v_i - step)' S1^-1 (v_i - step)`` below the chi-square bound, with
     at least ``event_confirm_windows`` windows) has ``T_j* > h_event`` (``event_probability``),
     *and* the innovation jumps there: from the window before ``j*`` to one of the next three,
     ``v_b - v_a`` exceeds ``h_event`` under its AR(1) covariance (variance ``2 (1 - phi^d) R`` per
     channel, the channels correlated as in ``R``) and twice the largest jump seen between ordinary
     neighbouring windows lately. A slow wander of autocorrelated noise drifts, a step jumps. The
     windows from ``j*`` on start a new segment; windows before it are handled as in *transient*;
   - *transient*: the latest window is back (closer to no change than to the step of the whole
     run): the earlier pending windows were a passing excursion, such as a test car. Those beyond
     ``h_outlier`` (``mahalanobis_probability``) are rejected as outliers, the others are ordinary
     windows; the latest window is judged afresh;
   - after ``event_max_pending`` windows a decision is forced: an event if a candidate qualifies,
     otherwise the whole run is ordinary windows (a long excursion that is not a step, such as a
     drift the model has no process noise for, is data, not outliers): no lock-out.

While the noise model rests on few windows, its variance is uncertain: detection uses it inflated
by ``dof / chi2_dof(0.05)`` (its one-sided 95 % bound; ``dof`` the fit's residual degrees of
freedom), so that the first hours of a record do not raise events from a noise level that is not
known yet; the comparison with the jumps seen so far guards the same hours (on the same, possibly
too small, scale, ordinary jumps look as large as a false event's).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import special, stats

from bridge_shadow.estimate.noise import ar1_factor
from bridge_shadow.estimate.small import Sym, Vec, quad_inv

__all__ = ["JUMP_MEMORY", "JUMP_OVER_SEEN", "ChangeDetector", "Decision", "Pending"]

#: An event's jump must exceed this many times the largest jump seen between ordinary windows.
JUMP_OVER_SEEN = 2.0
#: Per window, the largest ordinary jump is forgotten by this factor (a half-life of 70 windows).
JUMP_MEMORY = 0.99


def _arr(m: Sym) -> np.ndarray:
    return np.array([[m[0], m[1]], [m[1], m[2]]])


def _sym(m: np.ndarray) -> Sym:
    return (float(m[0, 0]), float(m[0, 1]), float(m[1, 1]))


@dataclass
class Pending:
    """One held window: index, innovation (2,) N, its covariance pieces (2, 2) N^2, and a payload."""

    k: int
    v: np.ndarray
    r_window: np.ndarray
    apa: np.ndarray
    payload: Any


@dataclass
class Decision:
    """What to do with held windows, in this order: reject, accept before, start an event, accept.

    Attributes:
        reject: payloads rejected as outliers.
        accept_before: payloads that are ordinary windows of the current segment (before an event).
        event: payloads that start a new segment (None: no event).
        step_n: (2,) N, estimated step of the innovations (event only).
        glr: the test statistic of the event (NaN otherwise).
        accept: payloads that are ordinary windows after the event (or without one).

    """

    reject: list[Any] = field(default_factory=list)
    accept_before: list[Any] = field(default_factory=list)
    event: list[Any] | None = None
    step_n: np.ndarray | None = None
    glr: float = float("nan")
    accept: list[Any] = field(default_factory=list)


@dataclass
class _Candidate:
    j: int
    glr: float
    step: np.ndarray
    consistent: bool
    jump: float


class ChangeDetector:
    """GLR step detector over window innovations (see the module docstring).

    Attributes:
        h_trigger, h_event, h_outlier, h_jump: chi-square(2) thresholds.
        confirm: windows after the change needed to confirm it; max_pending: forced decision.
        pending: the held windows; prev: the last ordinary window (the reference of the jump test).
        n_events: events raised; phi: (2,) the noise model's autocorrelation; inflation: see above.

    """

    def __init__(
        self,
        trigger_probability: float = 0.999,
        event_probability: float = 1.0 - 1e-6,
        outlier_probability: float = 1.0 - 1e-6,
        confirm: int = 4,
        max_pending: int = 15,
        consistency_probability: float = 0.999,
    ) -> None:
        self.h_trigger = float(stats.chi2.ppf(trigger_probability, 2))
        self.h_event = float(stats.chi2.ppf(event_probability, 2))
        self.h_jump = self.h_event
        self.h_outlier = (
            float("inf") if outlier_probability >= 1.0 else float(stats.chi2.ppf(outlier_probability, 2))
        )
        self.confirm = int(confirm)
        self.max_pending = int(max_pending)
        self._chi2_bound = [np.inf] + [
            float(stats.chi2.ppf(consistency_probability, 2 * k)) for k in range(1, 64)
        ]
        self.pending: list[Pending] = []
        self.prev: Pending | None = None
        self.max_jump = 0.0  # largest jump statistic between ordinary neighbours (slowly forgotten)
        self.n_events = 0
        self.phi = np.zeros(2)
        self.inflation = 1.0

    def set_noise(self, phi: np.ndarray, dof: float) -> None:
        """Use the noise model's autocorrelation; inflate its variance while it rests on few windows.

        ``dof`` is the residual degrees of freedom behind the variance estimate; the inflation
        ``dof / chi2_dof(0.05)`` is its one-sided 95 % upper bound over the estimate (2.4 after 13
        windows, 1.3 after 100, 1.06 after a day).
        """
        self.phi = np.asarray(phi, float).reshape(2)
        dof = max(float(dof), 1.0)
        self.inflation = float(dof / special.chdtri(dof, 0.95))

    def rebase(self, k: int, v: Vec) -> None:
        """Re-express the jump test's reference after a refit: window ``k``'s innovation is now ``v``.

        The jump test compares innovations of neighbouring windows; across a refit they refer to
        different estimates, so the reference window is re-expressed against the new one.
        """
        p = self.prev
        if p is not None and p.k == k:
            if isinstance(p.v, tuple):
                self.prev = Pending(k, v, p.r_window, p.apa, None)
            else:
                self.prev = Pending(k, np.array(v), p.r_window, p.apa, None)

    # -- per window -----------------------------------------------------------------------------
    def step(self, k: int, v: Vec, r_window: Sym, apa: Sym, payload: Any) -> Decision:
        """Take window ``k``'s innovation and return what to do with the held windows.

        ``v`` (N) with ``R1 / m`` and ``A P A'`` (N^2, symmetric 2x2 as ``(a, b, d)`` floats).
        """
        infl = self.inflation
        if not self.pending:
            total = (r_window[0] * infl + apa[0], r_window[1] * infl + apa[1], r_window[2] * infl + apa[2])
            if quad_inv(total, v) <= self.h_trigger:  # the common case, on floats
                self._note_jump(k, v, r_window)
                self.prev = Pending(k, v, r_window, apa, None)  # kept lazily as floats
                return Decision(accept=[payload])
        item = Pending(k, np.array(v), _arr(r_window) * infl, _arr(apa), payload)
        if not self.pending:
            self.pending = [item]
            return Decision()
        self.pending.append(item)
        cands = self._candidates()
        if self._d2(item, np.zeros(2)) < self._d2(item, cands[0].step):
            return self._transient()  # back to where the run started from: it was passing by
        best = self._best(cands)
        n_after = len(self.pending) - best.j
        if self._qualifies(best) and best.consistent and n_after >= self.confirm:
            return self._event(best)
        if len(self.pending) >= self.max_pending:
            forced = max(self._candidates(), key=lambda c: c.glr if self._qualifies(c) else -1.0)
            if self._qualifies(forced):
                return self._event(forced)
            return self._release_all(reject_outliers=False)
        return Decision()

    def flush(self) -> Decision:
        """End of data: decide on what is held (an event needs the confirmation windows)."""
        if not self.pending:
            return Decision()
        best = self._best()
        if self._qualifies(best) and best.consistent and len(self.pending) - best.j >= self.confirm:
            return self._event(best)
        return self._release_all(reject_outliers=len(self.pending) < self.max_pending)

    # -- internals ------------------------------------------------------------------------------
    def _qualifies(self, c: _Candidate) -> bool:
        return c.glr > self.h_event and c.jump > max(self.h_jump, JUMP_OVER_SEEN * self.max_jump)

    def _note_jump(self, k: int, v: Vec, r_window: Sym) -> None:
        """Track the largest jump statistic between neighbouring ordinary windows (slowly forgotten).

        An event's jump must stand out from those too: early in a record, while the noise model
        still underestimates the scatter, ordinary jumps look large on the same wrong scale.
        """
        p = self.prev
        self.max_jump *= JUMP_MEMORY
        if p is None or not isinstance(p.v, tuple) or not 0 < k - p.k <= 3:
            return
        fa = 1.0 - self.phi[0] ** (k - p.k)
        fb = 1.0 - self.phi[1] ** (k - p.k)
        a0, b0, d0 = p.r_window
        a1, b1, d1 = r_window
        ra, rb, rd = a0 + a1, b0 + b1, d0 + d1
        # V = the jump covariance of ``_jump`` (per-channel AR(1) variance, the channels' correlation)
        scale = math.sqrt(max(fa, 1e-6) * max(fb, 1e-6))
        V = (ra * max(fa, 1e-6), rb * scale, rd * max(fb, 1e-6))
        j = quad_inv(V, (v[0] - p.v[0], v[1] - p.v[1])) / self.inflation
        if j > self.max_jump:
            self.max_jump = j

    @staticmethod
    def _d2(item: Pending, step: np.ndarray) -> float:
        d = item.v - step
        return float(d @ np.linalg.solve(item.r_window + item.apa, d))

    def _reference(self, j: int) -> Pending | None:
        """Return the window before candidate start ``j`` (a held one, or the last ordinary window)."""
        if j > 0:
            return self.pending[j - 1]
        p = self.prev
        if p is None:
            return None
        if isinstance(p.v, tuple):  # stored lazily by the fast path
            p = Pending(p.k, np.array(p.v), _arr(p.r_window) * self.inflation, _arr(p.apa), None)
            self.prev = p
        return p

    def _jump(self, j: int) -> float:
        """Largest jump statistic from the window before ``j`` to each of the next three windows.

        An AR(1) wander moves little between neighbours: on channel ``c``, ``v_b - v_a`` has the
        variance ``(1 - phi_c^d) (R_a + R_b)_cc`` for windows ``d`` apart (the estimate's own error
        cancels), with the channels correlated as in ``R``, while a step jumps by its full size.
        Without a reference window the test passes.
        """
        ref = self._reference(j)
        if ref is None:
            return np.inf
        best = 0.0
        for b in self.pending[j : j + 3]:
            r = ref.r_window + b.r_window
            sd = np.sqrt(np.diag(r))
            scale = sd * np.sqrt(np.maximum(1.0 - self.phi ** (b.k - ref.k), 1e-6))
            V = r / np.outer(sd, sd) * np.outer(scale, scale)
            diff = b.v - ref.v
            best = max(best, float(diff @ np.linalg.solve(V, diff)))
        return best

    def _candidates(self) -> list[_Candidate]:
        """Every start ``j`` of the pending run with its GLR, step, scatter check and jump test."""
        vs = np.array([p.v for p in self.pending])
        n = len(vs)
        out = []
        r_mean = np.mean([p.r_window for p in self.pending], axis=0)
        apa = self.pending[-1].apa
        sums = np.cumsum(vs[::-1], axis=0)[::-1]  # s_j = sum_{i >= j} v_i
        for j in range(n):
            nj = n - j
            f = ar1_factor(self.phi, nj)
            V = nj * np.sqrt(np.outer(f, f)) * r_mean + nj * nj * apa  # cov of s_j without a change
            s = sums[j]
            t = float(s @ np.linalg.solve(V, s))
            step = s / nj
            scatter = sum(self._d2(p, step) for p in self.pending[j:])
            bound = self._chi2_bound[min(nj - 1, len(self._chi2_bound) - 1)]
            out.append(_Candidate(j, t, step, bool(scatter <= bound), self._jump(j)))
        return out

    def _best(self, cands: list[_Candidate] | None = None) -> _Candidate:
        cands = self._candidates() if cands is None else cands
        good = [c for c in cands if c.consistent and c.jump > self.h_jump] or [
            c for c in cands if c.consistent
        ]
        return max(good or cands, key=lambda c: c.glr)

    def _split_ordinary(self, items: list[Pending]) -> tuple[list[Any], list[Any]]:
        """(rejected, ordinary) payloads among held windows judged as no change."""
        reject, ordinary = [], []
        for p in items:
            if self._d2(p, np.zeros(2)) > self.h_outlier:
                reject.append(p.payload)
            else:
                ordinary.append(p.payload)
                self.prev = p
        return reject, ordinary

    def _transient(self) -> Decision:
        *before, last = self.pending
        self.pending = []
        reject, ordinary = self._split_ordinary(before)
        again = self.step(
            last.k, tuple(last.v), _sym(last.r_window / self.inflation), _sym(last.apa), last.payload
        )
        return Decision(reject=reject + again.reject, accept_before=ordinary, accept=again.accept)

    def _event(self, c: _Candidate) -> Decision:
        before, after = self.pending[: c.j], self.pending[c.j :]
        self.pending = []
        self.n_events += 1
        reject, ordinary = self._split_ordinary(before)
        self.prev = None  # innovations after the event refer to a new estimate
        return Decision(
            reject=reject, accept_before=ordinary, event=[p.payload for p in after], step_n=c.step, glr=c.glr
        )

    def _release_all(self, reject_outliers: bool = True) -> Decision:
        items, self.pending = self.pending, []
        if not reject_outliers:  # a long excursion that is not a step is data, not outliers
            self.prev = items[-1]
            return Decision(accept_before=[p.payload for p in items])
        reject, ordinary = self._split_ordinary(items)
        return Decision(reject=reject, accept_before=ordinary)

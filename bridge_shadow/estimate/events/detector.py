"""Settlement-event detector: a generalized likelihood ratio (GLR) test for a step in the innovations.

Each window brings an innovation ``v = z - A x`` (N, 2) against the current settlement estimate,
with its single-window covariance ``S1 = R1 / m + A P A'`` (``NoiseModel.window_cov`` plus the
estimate's own uncertainty). Without a change, ``v' S1^-1 v`` is chi-square with two degrees of
freedom.

1. **Trigger.** A window with ``v' S1^-1 v > h_trigger`` (``event_trigger_probability``) starts a
   *pending* run; pending windows are held (not yet in the fit, the noise model or the output).
   So does a window within the trigger only by the estimate's own uncertainty ``A P A'`` (beyond
   it on the window noise ``R1 / m`` alone) that jumps from the last ordinary window as an
   event's change time must (the jump test below): ``A P A'`` is shared by every window and a
   jump does not see it, so a step smaller than it passed the trigger, and its jump counted as
   an ordinary one (``_note_jump``).
2. **GLR with change-time estimation.** For each candidate start ``j`` of the pending run of ``n``
   windows, the sum ``s_j = sum_{i >= j} v_i`` of its ``n_j`` windows has, without a change, the
   covariance ``V_j = F(n_j) o R1 / m + n_j^2 A P A'``, with ``F(n) = n f(n)`` the AR(1) variance of a
   sum of ``n`` windows (``noise.ar1_factor``: a slow wander of autocorrelated noise is not a step).
   The test statistic is ``T_j = s_j' V_j^-1 s_j`` and the step estimate ``s_j / n_j``.
3. **Decision** after each pending window, by one rule:

   - a candidate *qualifies* when its windows scatter around the step like noise
     (``sum (v_i - step)' S1^-1 (v_i - step)`` below the chi-square bound; or so with the creep a
     state may show after its change added along the step, ``_relaxing_scatter``), ``T_j > h_event``
     (``event_probability``), at least ``event_confirm_windows`` windows follow its start, and the
     innovation *jumps* there: from the window before ``j`` (before the one the step fell in, when
     the window before ``j`` is read as holding part of it) to one of the next ``JUMP_LOOKAHEAD``
     windows, ``v_b - v_a`` exceeds ``h_jump`` under its AR(1) covariance (variance
     ``2 (1 - phi^d) R`` per channel, the channels correlated as in ``R``) and ``JUMP_OVER_SEEN``
     times the largest jump seen between ordinary neighbouring windows lately; across a hole
     also after the progress the held windows' own rate makes over it (``_drift_jump``). A slow
     wander of autocorrelated noise drifts, a steady trend moves at its rate, a step jumps;
   - *event*: among the qualifying candidates, the change time is the one under which the whole
     run is most likely (windows before it scatter around no change, windows from it on around
     the step: the smallest ``sum_{i<j} d2(v_i, 0) + sum_{i>=j} d2(v_i, step_j)``; the window just
     before ``j`` may instead hold part of the step, ``MIXED_PENALTY``, and is then neither
     state). Choosing the change time and qualifying use the same criteria, so a run that
     qualifies is never lost to a neighbouring start that does not. The windows from ``j*`` on
     start a new segment; windows before it are handled as in *transient*, but for the last ones
     if they did not come back (two or more: an unconfirmed change of their own; one between the
     states: the window the step happened in; never outliers);
   - *transient*: the latest window is back (closer to no change than to the step of the whole
     run, and within the trigger of no change): the earlier pending windows were a passing
     excursion, such as a test car. Those beyond ``h_outlier`` (``mahalanobis_probability``) are
     rejected as outliers, the others are ordinary windows; the latest window is judged afresh.
     Only a run that came back loses windows; one whose latest window left it the other way,
     beyond the trigger (a drift, then a step), did not come back: it is decided as a run that
     stayed away (below), the latest window judged afresh (``_moved_on``); when that run is a
     state in all but its length that no vehicle makes (``_short_state``), it starts a
     provisional segment as at the end of the data, and the latest window is judged against it;
   - *unconfirmed change*: a run that has not come back but must be decided without a qualifying
     candidate (after ``event_max_pending`` windows, at the end of the data, or at the start of a
     gap, see ``close_run``) is never rejected: it starts a *provisional* segment at its most
     likely change time, whose jump is uncertain (the shadow weighs "changed" against "not
     changed" by the data, ``segments``), and the shadow reports it; a run that holds two
     states, the second a step no vehicle makes, is two such changes (``_second_state``). At
     ``event_max_pending`` inside the data the run is ordinary data, the change reported; when
     its most likely change time has fewer than ``event_confirm_windows`` windows after it, only
     the windows before it are decided so and the rest stay held (``_forced``). A run that still
     moves on the known noise then (a ramp) is held on until it is still and read where it moved
     and stopped (``_long_run``), and one that moves so is not an event before that either (one
     hold, before and after ``event_max_pending``); one window before a gap, no heavier than any
     vehicle, is no state of its own (``close_run``).

While the noise model rests on few windows, its variance is uncertain: detection uses it inflated
by ``dof / chi2_dof(0.05)`` (its one-sided 95 % bound; ``dof`` the fit's residual degrees of
freedom), so that the first hours of a record do not raise events from a noise level that is not
known yet; the comparison with the jumps seen so far guards the same hours (on the same, possibly
too small, scale, ordinary jumps look as large as a false event's).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np
from scipy import special, stats

from bridge_shadow.estimate.compensation.noise import ar1_factor
from bridge_shadow.estimate.events.warmup import (
    RAMP_HOLD_FACTOR,
    beyond_any_vehicle,
    moved_not_still,
    moved_then_still,
    moving_on_known_noise,
    ramp_in_progress,
    ramp_windows,
)
from bridge_shadow.estimate.result import CHI2_2DOF_95
from bridge_shadow.estimate.settlement.relaxation import relaxation_variance
from bridge_shadow.estimate.small import Sym, Vec, quad_inv

__all__ = [
    "JUMP_LOOKAHEAD",
    "JUMP_MEMORY",
    "JUMP_OVER_SEEN",
    "MIXED_PENALTY",
    "RAMP_HISTORY",
    "SHORT_STATE_WINDOWS",
    "ChangeDetector",
    "Decision",
    "Pending",
]

#: An event's jump must exceed this many times the largest jump seen between ordinary windows.
#:
#: Derivation: without a change a jump statistic is ``c X`` with ``X`` chi-square(2) (exponential,
#: mean 2) and ``c`` the factor by which the noise model misjudges the scatter (1 when it is right;
#: above 1 early in a record or on a real bridge whose residuals are not AR(1)). The largest of the
#: ``n`` ordinary jumps remembered is ``c M_n``. With ``U = exp(-M_n / 2)``, ``U`` is the minimum of
#: ``n`` uniforms, and ``P(c X > f c M_n) = E[U^f] = n B(f + 1, n) = Gamma(f + 1) n! / (n + f)!``:
#: the false-jump probability of the rule does not depend on ``c`` at all. With ``f = 2`` and the
#: ``n ~ 1 / (1 - JUMP_MEMORY) = 100`` windows remembered it is ``2 / (101 * 102) = 1.9e-4`` per
#: window, the order of the trigger's ``1 - event_trigger_probability = 1e-3``: a misjudged noise
#: scale cannot raise events faster than that, while a true step of a few sigma clears ``2 M_n``
#: (``test_estimate_events`` pins both sides). ``f = 1`` would allow 1 % per window.
JUMP_OVER_SEEN = 2.0
#: Per window, the largest ordinary jump is forgotten by this factor (a half-life of 70 windows,
#: about ``n = 100`` windows remembered in the derivation above).
JUMP_MEMORY = 0.99
#: The jump test compares the window before a candidate start with this many windows from it on.
#:
#: Derivation: a step inside window ``j`` (not at its boundary) puts only a fraction of itself into
#: ``v_j``; the full step shows in ``v_{j+1}``. A change that takes up to two windows (lowering a
#: support with jacks, a minute or two) shows fully in ``v_{j+2}``. Three windows cover both; the
#: test ``test_a_two_window_ramp_needs_the_look_ahead`` pins it.
JUMP_LOOKAHEAD = 3
#: The price, in ``-2 log L``, of the fraction a step took of the window before a change time.
#:
#: Derivation: a change time ``j`` may come with the window before it holding the step for part of
#: its length (a step inside a window: ``v = f step``, ``0 < f < 1``; the windows after it hold
#: all of it). That reading has one parameter more than "the window before ``j`` is the old
#: state", so it always fits at least as well; it is taken only when it fits better by more than
#: the likelihood-ratio test of one parameter at the trigger's level allows (chi-square(1) at
#: 0.999, 10.8), and only after ``2 event_confirm_windows`` windows from ``j`` (the last window of
#: a ramp over several reads the same way: the ramp rule, which needs the windows after the ramp,
#: looks first; ``test_a_ramp_in_continuous_data...`` keeps its verdicts). Without it, a step a
#: quarter into a window made the likeliest change time the mixed window itself, whose scatter
#: around the step fails the consistency test: the run waited for ``event_max_pending`` windows,
#: was used as data of the old state, and the event came 15 windows late (twin, three days at
#: 1 Hz; ``test_estimate_events`` pins it).
MIXED_PENALTY = float(stats.chi2.ppf(0.999, 1))
#: Windows a short state needs from its change time to be kept as a provisional change when the
#: data leave it the other way (``ChangeDetector._moved_on``), or to be reported as an excursion
#: no vehicle makes when they come back (``_transient``): two, as a change no vehicle makes
#: across a gap (``settlement.segments.GAP_LOWERING_WINDOWS``), because one window alone between
#: two other levels is what an outlier, or the window a step happened in, looks like.
SHORT_STATE_WINDOWS = 2
#: Ordinary windows remembered before a run (the old state's differences, which the ramp rule of
#: ``events.warmup`` measures a ramp in the run against: at least ``RAMP_MIN_REST`` and a few more).
RAMP_HISTORY = 4


@lru_cache(maxsize=8)
def _scatter_bounds(probability: float) -> tuple[float, ...]:
    """Return chi-square quantiles with ``2 i`` degrees of freedom at index ``i``.

    The bound of the scatter of ``i + 1`` windows around their mean, whose step is estimated from
    them; index 0 is never a bound.
    """
    return (np.inf, *(float(stats.chi2.ppf(probability, 2 * k)) for k in range(1, 64)))


def _quad(m: np.ndarray, v: np.ndarray) -> float:
    """``v' M^-1 v`` for a symmetric positive definite 2x2 ``M`` (closed form, ``small.quad_inv``).

    Every matrix here is symmetric by construction (sums and elementwise products of symmetric
    ones); ``np.linalg.solve`` spent 10 us a call on a 2x2, thousands of times per held run.
    """
    a, b, _, d = m.ravel().tolist()
    x, y = v.tolist()
    return quad_inv((a, b, d), (x, y))


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
    """What to do with held windows, in this order: reject, accept before, start a segment, accept.

    Attributes:
        reject: payloads rejected as outliers (a short excursion that came back).
        accept_before: payloads that are ordinary windows of the current segment (before a change).
        event: payloads that start a new segment after a confirmed event (None: no event).
        change: payloads that start a provisional segment: an unconfirmed change at the end of a
            run that ended with the data or at a gap (None: none).
        unconfirmed: payloads of a run that reached ``event_max_pending`` without qualifying: they
            are also in ``accept_before`` (ordinary data), and the shadow reports the change.
        step_n: (2,) N, estimated step of the innovations (event or change only).
        step_cov_n2: (2, 2) N^2, its covariance (an unconfirmed change only).
        glr: the test statistic of the event or change (NaN otherwise).
        accept: payloads that are ordinary windows after the event (or without one).
        moving: payloads of a run's windows that moved from the old state to the new one over
            several windows (a ramp, ``ChangeDetector._ramp_split``): neither state.
        drift: the ``unconfirmed`` run jumped over a hole only as far as its own rate carried it
            (``ChangeDetector._drift_jump``): a drift, reported as not significant.
        rejudge: payloads to judge afresh once the decided windows are applied: their innovation
            refers to the estimate before the provisional segment this decision starts
            (``ChangeDetector._moved_on``).
        excursion: the payloads of ``reject`` when they are a run that came back after moving the
            reactions' sum by more than any vehicle (``ChangeDetector._transient``): rejected as
            an excursion, and reported as a possible short change; ``excursion_n``: (2,) N, its
            mean innovation, ``excursion_cov_n2``: (2, 2) N^2, that mean's covariance. With
            ``between_steps``: the windows beyond any vehicle of a ``moving`` run the data left
            for another level (``ChangeDetector._moved_on``), a state held between two steps.
        between_steps: ``excursion`` is such a state between two steps, not a run that came back.
        before_gap: ``excursion`` is the one window of a ``moving`` run before a gap, no heavier
            than any vehicle (``ChangeDetector.close_run``): no state of its own, reported.
        at_end: the same at the end of the data (a vehicle that drove on in the data's last
            window, or the window a step happened in): no state of its own, reported.

    """

    reject: list[Any] = field(default_factory=list)
    accept_before: list[Any] = field(default_factory=list)
    event: list[Any] | None = None
    change: list[Any] | None = None
    unconfirmed: list[Any] | None = None
    step_n: np.ndarray | None = None
    step_cov_n2: np.ndarray | None = None
    glr: float = float("nan")
    accept: list[Any] = field(default_factory=list)
    moving: list[Any] = field(default_factory=list)
    drift: bool = False
    rejudge: list[Any] = field(default_factory=list)
    excursion: list[Any] = field(default_factory=list)
    excursion_n: np.ndarray | None = None
    excursion_cov_n2: np.ndarray | None = None
    between_steps: bool = False
    before_gap: bool = False
    at_end: bool = False


@dataclass
class _Candidate:
    j: int
    glr: float
    step: np.ndarray
    consistent: bool
    jump: float
    cost: float  # -2 log-likelihood of the whole run with the change at j (up to a constant)
    n_after: int
    mixed: bool = False  # the cost reads the window before j as holding part of the step


class ChangeDetector:
    """GLR step detector over window innovations (see the module docstring).

    Attributes:
        h_trigger, h_event, h_outlier, h_jump: chi-square(2) thresholds.
        confirm: windows after the change needed to confirm it; max_pending: forced decision.
        pending: the held windows; prev: the last ordinary window (the reference of the jump test).
        n_events: events raised; phi: (2,) the noise model's autocorrelation; inflation: see above.
        window_s, relaxation_phi0, relaxation_horizon_s: the creep a candidate's windows may show
            in the scatter test (``_relaxing_scatter``; ``relaxation_phi0`` 0: none).
        vehicle_max_n: the heaviest vehicle on the reactions' sum, N (``traffic_vehicle_max_n``):
            a short state that moved the sum by more is no vehicle's (``_moved_on``).

    """

    def __init__(
        self,
        trigger_probability: float = 0.999,
        event_probability: float = 1.0 - 1e-6,
        outlier_probability: float = 1.0 - 1e-6,
        confirm: int = 4,
        max_pending: int = 15,
        consistency_probability: float = 0.999,
        window_s: float = 60.0,
        relaxation_phi0: float = 0.0,
        relaxation_horizon_s: float = 0.0,
        vehicle_max_n: float = math.inf,
    ) -> None:
        self.false_trigger = 1.0 - float(trigger_probability)
        self.h_trigger = float(stats.chi2.ppf(trigger_probability, 2))
        self.h_event = float(stats.chi2.ppf(event_probability, 2))
        self.h_jump = self.h_event
        self.h_outlier = (
            float("inf") if outlier_probability >= 1.0 else float(stats.chi2.ppf(outlier_probability, 2))
        )
        self.confirm = int(confirm)
        self.max_pending = int(max_pending)
        self._chi2_bound = _scatter_bounds(float(consistency_probability))
        self.window_s = float(window_s)
        self.relaxation_phi0 = float(relaxation_phi0)
        self.relaxation_horizon_s = float(relaxation_horizon_s)
        self.vehicle_max_n = float(vehicle_max_n)
        self.pending: list[Pending] = []
        self.prev: Pending | None = None
        self.max_jump = 0.0  # largest jump statistic between ordinary neighbours (slowly forgotten)
        self.max_jump_before = 0.0  # ``max_jump`` before the last window taken as data noted its jump
        self.n_events = 0
        # factors that depend on ``phi`` and a window count only, by count (cleared as ``phi`` is set)
        self._lag_factors: dict[int, tuple[float, float]] = {}
        self._run_factors: dict[int, np.ndarray] = {}
        self.phi = np.zeros(2)
        self.inflation = 1.0
        self.history: deque[tuple[int, float, float]] = deque(maxlen=RAMP_HISTORY)
        # the last window of the last run left out as a state between two steps, and that state's
        # level (``_moved_on``): the window after it may hold the second step
        self.left_k = -2
        self.left_level = np.zeros(2)

    @property
    def phi(self) -> np.ndarray:
        """(2,) the noise model's lag-one autocorrelation per channel (``set_noise``)."""
        return self._phi

    @phi.setter
    def phi(self, value: np.ndarray) -> None:
        self._phi = value
        self._lag_factors.clear()
        self._run_factors.clear()

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
            jump = self._ordinary_jump(k, v, r_window, apa)
            if jump is not None:  # the common case, on floats
                self.max_jump_before = self.max_jump
                self._note_jump(jump)
                self._remember(k, v)
                self.prev = Pending(k, v, r_window, apa, None)  # kept lazily as floats
                return Decision(accept=[payload])
        item = Pending(k, np.array(v), _arr(r_window) * infl, _arr(apa), payload)
        if not self.pending:
            self.pending = [item]
            return Decision()
        self.pending.append(item)
        cands = self._candidates()
        back = self._d2(item, np.zeros(2))
        if back < self._d2(item, cands[0].step):  # nearer the old state than the run's
            if back <= self.h_trigger:
                return self._transient()  # back to where the run started from: it was passing by
            return self._moved_on()  # beyond it, the other way: the run never came back
        best = self._best(cands)
        if len(self.pending) >= self.max_pending:
            return self._long_run(cands, best)
        if best is not None:
            series = self._run_series()
            split = self._ramp_split(series)
            if split is None and best.mixed and best.n_after < 2 * self.confirm:
                return Decision()  # a window inside the step, or a ramp's last: the ramp rule looks first
            if split is not None and len(self.pending) - split[1] < self.confirm:
                return Decision()  # a ramp ended: its new state needs its own windows first
            if split is None and ramp_in_progress(series[0], series[1], self.false_trigger):
                return Decision()  # still moving: the new state is not reached yet
            if self._still_moving(series, self._known_cov()):
                return Decision()  # moving on the known noise, as ``_long_run`` holds on: not still yet
            return self._event(best, split)
        return Decision()

    def _long_run(self, cands: list[_Candidate], best: _Candidate | None) -> Decision:
        """Decide a run held ``event_max_pending`` windows, or hold on while a ramp goes on.

        At ``event_max_pending`` a run is decided: an event at its best candidate (a ramp's
        windows left out, ``_ramp_split``, when its new state has ``event_confirm_windows``), or
        ordinary data with the change reported (``_forced``). A ramp slower than that (jacks
        lowering a support over a quarter of an hour) was still moving then: taken as data, its
        windows pulled the state and the noise model, and the day's earlier events fell to
        unconfirmed changes (``benchmarks/loadtest_days.py --only ramps``, the test car as
        recorded). So while the run moves on the known noise (``moving_on_known_noise``, as the
        hold after a gap reads it), and after that until its last ``RAMP_MIN_REST`` differences are
        still, it is held on, up to ``RAMP_HOLD_FACTOR`` times ``event_max_pending``. A run held on
        is then split where it moved and stopped (``_ramp_split``, else ``moved_then_still`` with
        the test car's moves among the moving windows): the moving windows left out, the new state
        an event when a candidate qualifies, a provisional change otherwise, once it has
        ``event_confirm_windows`` windows (or the hold's limit is reached). Before
        ``event_max_pending`` the same hold keeps such a run from being an event (``step``): over
        minutes 6-36 of the ramp study the test car's weight hid the jacks' pace, an event was
        dated four minutes into the lowering, and its still-lowering windows raised the noise
        model ninefold, so the rest of the lowering came as data (8.8 mm off at the end).
        """
        n = len(self.pending)
        series, cov = self._run_series(), self._known_cov()
        cap = n >= RAMP_HOLD_FACTOR * self.max_pending
        if not cap and self._still_moving(series, cov):
            return Decision()  # a ramp going on: its new state is not reached yet
        split = self._ramp_split(series)
        if split is None:
            split = self._moved_split(series, cov)
        if split is not None and n - split[1] < self.confirm and not cap:
            return Decision()  # a ramp ended: its new state needs its own windows first
        if best is not None:
            if split is not None and n - split[1] < self.confirm:
                split = None  # forced: the event as the one step dates it
            return self._event(best, split)
        if split is not None and n - split[1] >= SHORT_STATE_WINDOWS:
            return self._unconfirmed(cands, provisional=True, split=split)
        return self._forced(cands)

    def _known_cov(self) -> np.ndarray:
        """Return the noise model's covariance (2, 2) N^2 of a held window's mean, averaged, not inflated."""
        return np.mean([p.r_window for p in self.pending], axis=0) / self.inflation

    def _still_moving(self, series: tuple[np.ndarray, np.ndarray, int], cov: np.ndarray) -> bool:
        """Whether the held run moves on the known noise ``cov``, or moved and is not still yet.

        ``moving_on_known_noise`` on the remembered windows and the run, ``moved_not_still`` on
        the run and the ordinary window before it (as ``_moved_split`` reads it).
        """
        y, ks, h = series
        if moving_on_known_noise(y, ks, cov, self.phi, self.false_trigger):
            return True
        a = max(h - 1, 0)
        return moved_not_still(y[a:], ks[a:], cov, self.phi, self.false_trigger)

    def _moved_split(
        self, series: tuple[np.ndarray, np.ndarray, int], cov: np.ndarray | None = None
    ) -> tuple[int, int] | None:
        """``(first moving, first of the new state)`` in the held run where it moved and stopped."""
        y, ks, h = series
        a = max(h - 1, 0)  # the run and the ordinary window before it (the old state's wander not read)
        cov = self._known_cov() if cov is None else cov
        found = moved_then_still(
            y[a:], ks[a:], cov, self.phi, self.false_trigger, self.vehicle_max_n, one_sign=False
        )
        if found is None or found[1] + a <= h:
            return None
        return max(found[0] + a - h, 0), found[1] + a - h

    def close_run(self, at_gap: bool = False, at_end: bool = False) -> Decision:
        """Decide on what is held because the run ends here: at the end of the data or a gap.

        A run that is held has not come back (its last window was closer to the step than to no
        change), so it is an event if a candidate qualifies, and an unconfirmed change otherwise:
        never outliers. When the likeliest change time jumps only as far as the held windows' own
        rate carries them over a hole (``_drift_jump``), the run is a drift: ordinary data, the
        change reported (``Decision.drift``), whether or not its jump without the rate passes the
        bound (one within it was a provisional change, which its level alone then confirmed: the
        reference record's own rise over the test car's minutes, 0.43 kN, a second event of +0.1
        mm; ``benchmarks/loadtest_days.py --only sweep --seeds 1000 --stream-seed 41``, #640). A
        lone window within the trigger, held for its jump, is data as before the jump rule (the
        real reference record cut at 2.5 minutes, 4 h on and 20 mm lower: its last window, half of
        one, jumped 1.1 mm and was a change at probability 1). A lone window beyond the trigger
        but no heavier than any vehicle is no state of its own (``SHORT_STATE_WINDOWS``): it is
        left out and reported. Before a gap (``Decision.before_gap``) the gap's segment weighs any
        change by the windows after it (a test car that came on in a cut record's last seconds
        was a change of probability 1, and the next record's return a second event). At the end
        of the data (``at_end``, from ``flush``; ``Decision.at_end``) nothing follows that could
        tell a vehicle that drove on in the last window from the window a step happened in: taken
        as a change, a vehicle's load moved the final estimate by the whole of it at probability 1
        (a record cut 9 s after the test car drove on, +1.5 mm, ``benchmarks/loadtest_days.py
        --only sweep --seeds 600 --stream-seed 53 --cut-share 1.0``, #253; a day of continuous
        monitoring cut as a vehicle crossed, +0.3 mm and a change warned of). There, only a window
        right after the state's data: one after a window left out is the last state's (a raise
        inside minute 11 of a record lowered at minute 9, ``--only inside --stream-seed 71``,
        #272, 1.1 mm off as a vehicle's).
        """
        if not self.pending:
            return Decision()
        if len(self.pending) == 1 and self._d2(self.pending[0], np.zeros(2)) <= self.h_trigger:
            # one window held for its jump, nothing after it to say whether the level stayed (a
            # step, or a car arriving at the end of a record): data, as any within the trigger
            only = self.pending.pop()
            self._remember(only.k, only.v)
            self.prev = only
            return Decision(accept=[only.payload])
        lone = len(self.pending) == 1 and not self._beyond_any_vehicle(self.pending[0].v)
        # at the end, only right after a window of the state's data: after a window left out (the
        # one a second step happened in, ``_second_step_inside``) it is the last state's window
        after_data = self.prev is not None and self.prev.k == self.pending[0].k - 1
        if lone and (at_gap or (at_end and after_data)):
            # one window where the run ends, no heavier than any vehicle: no state of its own
            # (``SHORT_STATE_WINDOWS``), neither a vehicle's outlier (it did not come back) nor
            # this state's data; after a gap, the gap's segment weighs any change by its windows
            only = self.pending.pop()
            return Decision(
                moving=[only.payload],
                excursion=[only.payload],
                excursion_n=np.array(only.v, float),
                excursion_cov_n2=self._mean_cov([only]),
                before_gap=at_gap,
                at_end=at_end,
            )
        cands = self._candidates()
        best = self._best(cands)
        series = self._run_series()
        split = self._ramp_split(series)
        if split is None and len(self.pending) >= self.max_pending:
            split = self._moved_split(series)  # a run held on (``_long_run``) that stopped
        if best is not None and (split is None or len(self.pending) - split[1] >= self.confirm):
            return self._event(best, split)  # (a ramp's new state too short to confirm: a change)
        c = min(cands, key=lambda c: c.cost)
        if split is None and self._jump_bound() >= self._drift_jump(c.j):
            return self._unconfirmed(cands, provisional=False, drift=True)  # a drift: data, reported
        second = None if split is not None else self._second_state(c)
        if second is not None:  # two states held: the first a provisional change, the second judged on it
            b, mixed = second
            between = [self.pending[b - 1].payload] if mixed else []
            self.pending, rest = self.pending[: b - int(mixed)], self.pending[b:]
            decision = self._unconfirmed(self._candidates(), provisional=True)
            decision.moving += between  # the window the second step happened in: neither state
            decision.rejudge = [p.payload for p in rest]
            return decision
        return self._unconfirmed(cands, provisional=True, split=split)

    def flush(self) -> Decision:
        """End of data: decide on what is held (``close_run`` with ``at_end``)."""
        return self.close_run(at_end=True)

    # -- internals ------------------------------------------------------------------------------
    def _second_state(self, c: _Candidate) -> tuple[int, bool] | None:
        """Return where a second state begins in the held run, or None when it holds one at most.

        A run decided where it ends (the end of the data, a gap) is one change at its likeliest
        change time ``c``, the windows before it the old state's. It may hold two: a lowering in
        a record's first minute and a further one minutes later, the test car parked between.
        Read as one, the first state's windows were the old state's data, or one level held both;
        the residuals carried a step, and the adaptive noise model grew by orders of magnitude
        (seed 0's streams of ``twin.real_records.random_inside_streams``: 6,400 to 87,000 times
        its first variance on every stream that ended outside 10 % or its interval), after which
        no change of the day was significant. The run is read instead as the old state up to
        ``a``, a first state ``[a, b)`` and a second ``[b, n)`` (each at its mean, at least
        ``SHORT_STATE_WINDOWS`` windows each; window ``a - 1`` may hold the first step and window
        ``b - 1`` the second for part of their length, as a change time's window before it may:
        ``MIXED_PENALTY``, each then neither state; after such a window the second state may be
        one window, the step seen in two, as at the end of a record whose second settlement came
        in its last two minutes: seed 0's #34 and #224 ended 4.9 and 4.4 mm off as one change),
        at the ``a, b`` under which it is most likely. That reading
        stands when it fits better than ``c`` by more than an event's GLR (``h_event``: one change
        more, by the event's test) and its second step moves the reactions' sum by more than any
        vehicle (``vehicle_max_n``: the test car parked or leaving shifts a level too, by less).
        The first state is then decided as a run at its end is (windows that stayed away before a
        change time are a state of their own, as in ``_event``), and the second's windows are
        judged against it (``Decision.rejudge``). Returns ``b`` and whether window ``b - 1`` is
        the mixed one, or None.
        """
        n, short = len(self.pending), SHORT_STATE_WINDOWS
        if n < 2 * short:
            return None
        # prefix sums of C^-1, C^-1 v and v' C^-1 v: any range's scatter about any level in O(1)
        inv = np.linalg.inv(np.array([p.r_window + p.apa for p in self.pending]))
        vs = np.array([p.v for p in self.pending])
        wv = np.einsum("nij,nj->ni", inv, vs)
        cum_w = np.concatenate([np.zeros((1, 2, 2)), np.cumsum(inv, axis=0)])
        cum_wv = np.concatenate([np.zeros((1, 2)), np.cumsum(wv, axis=0)])
        cum_q = np.concatenate([[0.0], np.cumsum(np.einsum("ni,ni->n", vs, wv))])
        cum_v = np.concatenate([np.zeros((1, 2)), np.cumsum(vs, axis=0)])

        def scatter(i: int, j: int) -> tuple[float, np.ndarray]:
            """Scatter of windows ``[i, j)`` about their mean, and the mean."""
            m = (cum_v[j] - cum_v[i]) / (j - i)
            q = cum_q[j] - cum_q[i] - 2.0 * m @ (cum_wv[j] - cum_wv[i]) + m @ (cum_w[j] - cum_w[i]) @ m
            return float(q), m

        best: tuple[float, int, bool, np.ndarray] | None = None
        for a in range(n - 2 * short + 1):
            for b in range(a + short, n):
                q2, m2 = scatter(b, n)
                q1, m1 = scatter(a, b)
                options = [(q1 + q2, m1, False)] if n - b >= short else []
                if b - 1 - a >= short:  # or window ``b - 1`` held the second step (``MIXED_PENALTY``)
                    q1, m1 = scatter(a, b - 1)
                    p = self.pending[b - 1]
                    inside = self._d2_inside(Pending(p.k, p.v - m1, p.r_window, p.apa, None), m2 - m1)
                    options.append((q1 + inside + MIXED_PENALTY + q2, m1, True))
                for tail, m1, mixed in options:
                    before = float(cum_q[a])  # windows before ``a`` at no change
                    if a >= 1:  # or window ``a - 1`` held the first step, as a change time's may
                        inside = self._d2_inside(self.pending[a - 1], m1) + MIXED_PENALTY
                        before = min(before, float(cum_q[a - 1]) + inside)
                    if best is None or before + tail < best[0]:
                        best = (before + tail, b, mixed, m2 - m1)
        assert best is not None
        cost, b, mixed, step = best
        if cost < c.cost - self.h_event and self._beyond_any_vehicle(step):
            return b, mixed
        return None

    def _qualifies(self, c: _Candidate) -> bool:
        """Return whether ``c`` passes the one rule of an event's change time (module docstring)."""
        return c.n_after >= self.confirm and self._steps_there(c)

    def _steps_there(self, c: _Candidate) -> bool:
        """Every test of ``_qualifies`` but the count: consistent, significant, and it jumps."""
        return (
            c.consistent
            and c.glr > self.h_event
            and c.jump > self._jump_bound()
            and self._drift_jump(c.j) > self._jump_bound()
        )

    def _short_state(self, c: _Candidate) -> bool:
        """Return whether ``c`` is a state too short to confirm that no vehicle makes.

        Every test of ``_qualifies`` but the count, at least ``SHORT_STATE_WINDOWS`` windows from
        its change time, and a step whose sum over the two bearings lies beyond the heaviest
        vehicle either way (more than a vehicle adds, or more than one leaving takes off an
        estimate made while it stood: ``vehicle_max_n``).
        """
        return c.n_after >= SHORT_STATE_WINDOWS and self._beyond_any_vehicle(c.step) and self._steps_there(c)

    def _beyond_any_vehicle(self, step: np.ndarray) -> bool:
        """Whether ``step`` (2,) N moved the reactions' sum by more than any vehicle, either way."""
        return beyond_any_vehicle(step, self.vehicle_max_n)

    def _moved_clear(self, c: _Candidate) -> bool:
        """Whether candidate ``c``'s step moved the sum beyond any vehicle, clear of no change at 95 %."""
        if not self._beyond_any_vehicle(c.step):
            return False
        return _quad(self._step_cov(c), c.step) > CHI2_2DOF_95

    def _drift_jump(self, j: int) -> float:
        """Return ``_jump`` from the window before ``j`` against the rate the held windows show.

        A step is a jump; a drift moves by its rate times the windows between. Without a hole the
        jump test compares neighbours, which a drift moves little; across a hole (the test car's
        minutes cut by the traffic screen) a steady trend moves far, and the AR(1) wander, slow
        where it was learned, cannot follow it: the trend's progress over the hole read as a jump
        (the real reference record 20 mm lower after the 10 mm record, under the air of another
        hour: its south bearing rising 0.06 kN a minute through the record, a +0.1 mm step after
        the car; 2 of 766 whole streams of ``benchmarks/loadtest_days.py --only sweep``). So the
        jump is also measured from where the rate of the held run's neighbouring windows (each
        side of ``j``, not across it; held windows share one estimate) would have taken the
        window before ``j``: ``v_b - v_a - d r``, with the covariance of the jump plus ``d^2`` that
        of ``r`` (the lag-one jump covariance over the number of neighbour pairs). Infinite where
        ``j`` follows the window before it without a hole (a ramp in continuous data moves at a
        rate too, and ``_ramp_split`` reads it) or without a neighbour pair (no rate is read): the
        jump test alone decides. Infinite too where the rate read lies nearer no rate than the one
        that carries the jump: ``r' C_r^-1 r`` (``_rate_statistic``) below that jump statistic,
        the likelihood ratio of the two at even odds, no constant. A pair or two read a rate only
        roughly, and a lowering's progress over a hole then fit that rough rate under the jump
        bound while the windows showed no rate at all: the 10 mm record 5.75 h on, lowered 4.4 mm
        in its last minute, read its two windows after the car as a drift (not significant), 5.2
        mm off with the interval missing the truth (``benchmarks/loadtest_days.py --only inside
        --stream-seed 7``, #42; the rate 0.10 against 12.7). The drift the rule was written for
        reads 12.6 against 4.0.
        """
        ref = self._reference(j)
        if ref is None or self.pending[j].k - ref.k <= 1:
            return np.inf
        pairs = [
            self.pending[i].v - self.pending[i - 1].v
            for i in range(1, len(self.pending))
            if i != j and self.pending[i].k - self.pending[i - 1].k == 1
        ]
        if not pairs:
            return np.inf
        rate = np.mean(pairs, axis=0)
        jump = self._jump(j, (rate, len(pairs)))
        if jump > self._rate_statistic(ref.r_window + self.pending[j].r_window, rate, len(pairs)):
            return np.inf  # the rate read is nearer no rate than the one that carries the jump
        return jump

    def _rate_statistic(self, r: np.ndarray, rate: np.ndarray, n: int) -> float:
        """Return ``r' C_r^-1 r`` for the rate read from ``n`` neighbour pairs (``_drift_jump``).

        ``C_r``: the lag-one jump covariance of ``_jump`` over ``n``; ``r``: the window covariances
        of ``j``'s reference and ``j`` summed, as there.
        """
        return _quad(self._lag_cov(r, 1) / n, rate)

    def takes_as_data(self, k: int, v: Vec, r_window: Sym, apa: Sym) -> bool:
        """Whether ``step`` would take window ``k`` as data at once (nothing is changed)."""
        return not self.pending and self._ordinary_jump(k, v, r_window, apa) is not None

    def _ordinary_jump(self, k: int, v: Vec, r_window: Sym, apa: Sym) -> float | None:
        """Return the jump from the last ordinary window of a window taken as data at once, or None.

        Within the trigger, and a jump no event's change time could be (``_jump_bound``) or within
        the trigger on the window noise alone. Within the trigger only by the estimate's own
        uncertainty (shared by every window, it cancels in a jump), and jumping as an event's
        change time must, a window is held and judged with the run (None).
        """
        infl = self.inflation
        total = (r_window[0] * infl + apa[0], r_window[1] * infl + apa[1], r_window[2] * infl + apa[2])
        if quad_inv(total, v) > self.h_trigger:
            return None
        jump = self._neighbour_jump(k, v, r_window)
        return jump if jump <= self._jump_bound() or self._within_noise(v, r_window) else None

    def _jump_bound(self) -> float:
        """Return the jump an event's change time must exceed (``_qualifies``)."""
        return max(self.h_jump, JUMP_OVER_SEEN * self.max_jump)

    def _neighbour_jump(self, k: int, v: Vec, r_window: Sym) -> float:
        """Return the jump statistic from the last ordinary window to window ``k`` (0 without one).

        The jump covariance is ``_jump``'s (per-channel AR(1) variance, the channels' correlation);
        windows more than ``JUMP_LOOKAHEAD`` apart are not neighbours.
        """
        p = self.prev
        if p is None or not isinstance(p.v, tuple) or not 0 < k - p.k <= JUMP_LOOKAHEAD:
            return 0.0
        fa = 1.0 - self.phi[0] ** (k - p.k)
        fb = 1.0 - self.phi[1] ** (k - p.k)
        a0, b0, d0 = p.r_window
        a1, b1, d1 = r_window
        ra, rb, rd = a0 + a1, b0 + b1, d0 + d1
        scale = math.sqrt(max(fa, 1e-6) * max(fb, 1e-6))
        V = (ra * max(fa, 1e-6), rb * scale, rd * max(fb, 1e-6))
        return quad_inv(V, (v[0] - p.v[0], v[1] - p.v[1])) / self.inflation

    def _within_noise(self, v: Vec, r_window: Sym) -> bool:
        """Return whether ``v`` is within the trigger on the window noise alone (without ``A P A'``)."""
        infl = self.inflation
        return quad_inv((r_window[0] * infl, r_window[1] * infl, r_window[2] * infl), v) <= self.h_trigger

    def take_back(self, k: int) -> None:
        """Forget window ``k``, the last taken as data at once, as a window that is no data after all.

        Its jump leaves the jump bound (``max_jump`` as it was before it) and it is no neighbour
        to jump from (``prev``, and the ramp rule's history, restart with the next window).
        """
        if self.prev is None or self.prev.k != k:
            return
        self.max_jump = self.max_jump_before
        self.prev = None
        self.history.clear()

    def _note_jump(self, jump: float) -> None:
        """Track the largest jump statistic between neighbouring ordinary windows (slowly forgotten).

        An event's jump must stand out from those too: early in a record, while the noise model
        still underestimates the scatter, ordinary jumps look large on the same wrong scale.
        """
        self.max_jump = max(self.max_jump * JUMP_MEMORY, jump)

    @staticmethod
    def _d2(item: Pending, step: np.ndarray, extra: np.ndarray | None = None) -> float:
        d = item.v - step
        cov = item.r_window + item.apa if extra is None else item.r_window + item.apa + extra
        return _quad(cov, d)

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

    def _jump(self, j: int, rate: tuple[np.ndarray, int] | None = None) -> float:
        """Largest jump statistic from the window before ``j`` to each of the next ``JUMP_LOOKAHEAD``.

        An AR(1) wander moves little between neighbours: on channel ``c``, ``v_b - v_a`` has the
        variance ``(1 - phi_c^d) (R_a + R_b)_cc`` for windows ``d`` apart (the estimate's own error
        cancels), with the channels correlated as in ``R``, while a step jumps by its full size.
        Without a reference window the test passes. ``rate``: a rate per window ``r`` read from that
        many neighbour pairs, the jump measured from ``d r`` (``_drift_jump``), its covariance
        ``d^2`` times the lag-one one over the pairs added.
        """
        ref = self._reference(j)
        if ref is None:
            return np.inf
        best = 0.0
        ra, rb, _, rd = ref.r_window.ravel().tolist()
        x0, y0 = ref.v.tolist()
        if rate is not None:
            rx, ry = rate[0].tolist()
        for b in self.pending[j : j + JUMP_LOOKAHEAD]:
            ba, bb, _, bd = b.r_window.ravel().tolist()
            r = (ra + ba, rb + bb, rd + bd)
            d = b.k - ref.k
            va, vb, vd = self._lag_cov_sym(r, d)
            x1, y1 = b.v.tolist()
            x, y = x1 - x0, y1 - y0
            if rate is not None:
                la, lb, ld = self._lag_cov_sym(r, 1)
                c = d * d / rate[1]
                va, vb, vd = va + la * c, vb + lb * c, vd + ld * c
                x, y = x - d * rx, y - d * ry
            best = max(best, quad_inv((va, vb, vd), (x, y)))
        return best

    def _lag_factor(self, d: int) -> tuple[float, float]:
        """``sqrt(max(1 - phi^d, 1e-6))`` per channel: the AR(1) wander's share over ``d`` windows."""
        g = self._lag_factors.get(d)
        if g is None:
            ga, gb = np.sqrt(np.maximum(1.0 - self.phi**d, 1e-6)).tolist()
            g = self._lag_factors[d] = (ga, gb)
        return g

    def _lag_cov_sym(self, r: Sym, d: int) -> Sym:
        """``_lag_cov`` on floats, ``r`` and the result symmetric ``(a, b, d)``.

        The same operations in the same order as the array version, so the same floats (the jump
        test runs for every candidate start of a held run; numpy's calls on a 2x2 cost more).
        """
        if not (r[0] > 0.0 and r[2] > 0.0):  # no variance on a channel (or NaN): the array's NaN
            return _sym(self._lag_cov(_arr(r), d))
        ga, gb = self._lag_factor(d)
        sa, sb = math.sqrt(r[0]), math.sqrt(r[2])
        ca, cb = sa * ga, sb * gb
        return (r[0] / (sa * sa) * (ca * ca), r[1] / (sa * sb) * (ca * cb), r[2] / (sb * sb) * (cb * cb))

    def _lag_cov(self, r: np.ndarray, d: int) -> np.ndarray:
        """Covariance of ``v_b - v_a``, ``d`` windows apart, of an AR(1) wander; ``r = R_a + R_b``."""
        sd = np.sqrt(np.diag(r))
        scale = sd * np.asarray(self._lag_factor(d))
        return r / np.outer(sd, sd) * np.outer(scale, scale)

    def _run_factor(self, n: int) -> np.ndarray:
        """``n sqrt(f f')``, ``f = ar1_factor(phi, n)``: a run's no-change sum covariance over ``R``."""
        w = self._run_factors.get(n)
        if w is None:
            f = ar1_factor(self.phi, n)
            w = self._run_factors[n] = n * np.sqrt(np.outer(f, f))
        return w

    def _candidates(self) -> list[_Candidate]:
        """Every start ``j`` of the pending run: GLR, step, scatter check, jump test, run likelihood."""
        vs = np.array([p.v for p in self.pending])
        n = len(vs)
        out = []
        r_mean = np.mean([p.r_window for p in self.pending], axis=0)
        apa = self.pending[-1].apa
        sums = np.cumsum(vs[::-1], axis=0)[::-1]  # s_j = sum_{i >= j} v_i
        # ``_d2`` of every window at once, the operations of ``small.quad_inv`` in its order, and
        # summed one window after the other as before (the same floats, without a call per window)
        cov = np.array([p.r_window + p.apa for p in self.pending])
        ca, cb, cd = cov[:, 0, 0], cov[:, 0, 1], cov[:, 1, 1]
        denom = ca * cd - cb * cb

        def d2_sum(j: int, step: np.ndarray) -> np.ndarray:
            """``_d2(p, step)`` of the windows from ``j`` on, their running sum (``[-1]``: all)."""
            x, y = vs[j:, 0] - step[0], vs[j:, 1] - step[1]
            return np.add.accumulate((cd[j:] * x * x - 2.0 * cb[j:] * x * y + ca[j:] * y * y) / denom[j:])

        before = np.concatenate([[0.0], d2_sum(0, np.zeros(2))])
        for j in range(n):
            nj = n - j
            V = self._run_factor(nj) * r_mean + nj * nj * apa  # cov of s_j without a change
            s = sums[j]
            t = _quad(V, s)
            step = s / nj
            scatter = float(d2_sum(j, step)[-1])
            bound = self._chi2_bound[min(nj - 1, len(self._chi2_bound) - 1)]
            consistent = scatter <= bound or self._relaxing_scatter(j, step) <= bound
            cost = float(before[j] + scatter)  # windows before j at no change, from j on at the step
            inside = False
            if j > 0:  # or the window before j held the step: part of it, at the fraction that fits
                mixed = float(before[j - 1] + self._d2_inside(self.pending[j - 1], step) + MIXED_PENALTY)
                inside = mixed + scatter < cost
                cost = min(cost, mixed + scatter)
            # a step inside the window before j jumps from the window before that one
            jump = self._jump(j - 1) if inside else self._jump(j)
            out.append(_Candidate(j, t, step, bool(consistent), jump, cost, nj, inside))
        return out

    def _relaxing_scatter(self, j: int, step: np.ndarray) -> float:
        """Return the scatter of the windows from ``j`` on around ``step``, which may relax after it.

        The reactions creep back by up to ``phi(t) step`` after a change (``settlement.relaxation``,
        the allowance the shadow gives a state after its change): the candidate's own windows get
        the same, along the step, within ``relaxation_horizon_s`` (``t`` from the middle of window
        ``j``). Only the scatter test reads it; the change time is chosen without it.
        """
        if self.relaxation_phi0 <= 0.0:
            return float("inf")
        k0, total = self.pending[j].k, 0.0
        for p in self.pending[j:]:
            t_s = (p.k - k0 + 0.5) * self.window_s
            if t_s > self.relaxation_horizon_s:
                total += self._d2(p, step)
            else:
                relax = relaxation_variance((step[0], step[1]), t_s, self.relaxation_phi0)
                total += self._d2(p, step, _arr(relax))
        return total

    @staticmethod
    def _fraction(item: Pending, step: np.ndarray) -> float:
        """Return the part ``f`` of ``step`` that best explains a window's innovation (``v ~ f step``)."""
        w = np.linalg.solve(item.r_window + item.apa, step)
        denom = float(step @ w)
        return float(item.v @ w) / denom if denom > 0 else float("nan")

    def _d2_inside(self, item: Pending, step: np.ndarray) -> float:
        """``d2(v, f step)`` at the ``f`` that fits, for a window the step happened inside.

        Only a window between the two states (``0 < f < 1``) can have held the step for part of
        its length; any other is infinitely unlikely under this reading (one beyond the step is
        no mixture of the two states).
        """
        f = self._fraction(item, step)
        return self._d2(item, f * step) if 0.0 < f < 1.0 else float("inf")

    def _best(self, cands: list[_Candidate]) -> _Candidate | None:
        """Return the most likely change time if it qualifies (None otherwise: wait, or unconfirmed)."""
        c = min(cands, key=lambda c: c.cost)
        return c if self._qualifies(c) else None

    def _split_ordinary(
        self, items: list[Pending], back: Pending | None = None
    ) -> tuple[list[Pending], list[Any]]:
        """(rejected windows, ordinary payloads) among held windows judged as no change.

        With ``back``, the window a run of one window came back in (``_transient``): the held
        window is rejected too if its reactions' sum lay beyond any vehicle from it, however wide
        the noise model and the estimate's uncertainty (a young state's): a load no vehicle makes,
        alone, that came back. Taken as data, a load of 80 kN over one window among the young
        windows moved the level by 2 kN and grew the noise model with it. Not for longer runs:
        applied to them, it rejected the vehicles of 30-60 kN that reviewing helpers' streams park
        for minutes, and with them windows of the new states those runs came back to (windows
        rejected 168 -> 515 on helper-48's 1,094 streams, new-state windows lost in 25 -> 48 of the
        first 1,198 of the stop-79 helper's).
        """
        reject: list[Pending] = []
        ordinary: list[Any] = []
        for p in items:
            far = back is not None and self._beyond_any_vehicle(p.v - back.v)
            if far or self._d2(p, np.zeros(2)) > self.h_outlier:
                reject.append(p)
            else:
                ordinary.append(p.payload)
                self._remember(p.k, p.v)
                self.prev = p
        return reject, ordinary

    def _transient(self) -> Decision:
        """Decide a run whose latest window is back: an excursion (its far windows outliers).

        Rejected windows, at least ``SHORT_STATE_WINDOWS`` of them, whose mean moved the reactions'
        sum by more than any vehicle (``vehicle_max_n``, either way) were no passing vehicle: they
        stay rejected (the run came back, and its level is not the state's; kept as a change, the
        next event was dated under the test car: docs/loadtest-days.md, "Settlements inside a record,
        at random", #93), and the decision carries them as an excursion to report (``Decision.excursion``).
        """
        *before, last = self.pending
        self.pending = []
        far, ordinary = self._split_ordinary(before, back=last if len(before) == 1 else None)
        again = self.step(
            last.k, tuple(last.v), _sym(last.r_window / self.inflation), _sym(last.apa), last.payload
        )
        reject = [p.payload for p in far] + again.reject
        decision = Decision(reject=reject, accept_before=ordinary, accept=again.accept)
        if len(far) >= SHORT_STATE_WINDOWS:
            mean = np.mean([p.v for p in far], axis=0)
            if self._beyond_any_vehicle(mean):
                decision.excursion = [p.payload for p in far]
                decision.excursion_n = mean
                decision.excursion_cov_n2 = self._mean_cov(far)
        return decision

    def _forced(self, cands: list[_Candidate]) -> Decision:
        """Decide a run at ``event_max_pending`` without a qualifying candidate.

        It stayed away unqualified: data, and the change reported (``_unconfirmed``); but a run
        that moved the reactions' sum by more than any vehicle, clear of no change at 95 %
        (``_moved_clear``), is a provisional change, weighed "changed" against "not changed" by the
        data, as a run at the end of the data is. Taken as data, such a run (a recording longer
        than the traffic hold, its test car unscreened and held by an early noise model as noise, 10
        mm lower from its 12th minute) pulled the old state's level and the noise model with it:
        -0.9 mm ± 9.4 for -20, no event, no warning (``test_continuous_recording.py``). When its
        likeliest change time lies among its last windows, fewer than ``event_confirm_windows``
        after it, that change cannot be judged yet: the windows before it are decided so, and
        the ones from it on stay held. (A drift of a quarter of an hour and then a step: the step's
        three windows were used as data with the drift, the event dated 18 windows late.)
        """
        c = min(cands, key=lambda c: c.cost)
        if c.j == 0 or c.n_after >= self.confirm:
            return self._unconfirmed(cands, provisional=self._moved_clear(c))
        rest = self.pending[c.j :]
        self.pending = self.pending[: c.j]
        decision = self._unconfirmed(self._candidates(), provisional=False)
        self.pending = rest
        return decision

    def _moved_on(self) -> Decision:
        """Decide a run whose latest window left it the other way, beyond the trigger of no change.

        A run that drifted one way (the sun leaving the deck: the reactions rose by 0.7 kN over a
        quarter of an hour) and then a step the other way (a lowering): the step's window lies
        nearer no change than the run's mean, but it is not back, and the run did not come back
        either. Taken as a transient, the run's windows were rejected as outliers (9-13 windows on
        4 of 100 sunny twin days on 2022-04-11's schedule). Now a run of two or more is decided as
        one that stayed away without qualifying (ordinary data, the change reported:
        ``_unconfirmed``), as ``_event`` keeps the windows before a step that did not come back;
        one window is an outlier as any. The latest window is judged afresh.

        A run that is a state in all but its length (``_short_state``: its likeliest change time
        passes every test of an event's but the ``event_confirm_windows`` after it, and it moved
        the reactions' sum by more than any vehicle) is a provisional change instead, as a run
        at the end of the data is: taken as the old state's data it pulled that level towards
        its own (a 17.6 mm lowering of three car-free minutes inside a record, then a raise:
        the record's final state read 4 mm off). The latest window is then judged against the
        new state, once the decided windows are applied (``Decision.rejudge``).

        Any other run with a window that moved the sum beyond any vehicle holds neither level:
        no state of its own (fewer than ``SHORT_STATE_WINDOWS`` from its change time, one window
        between two levels as the window a step happened in looks, or a change time that fails an
        event's tests: the windows of a step, or of two, not a level), and no vehicle's load on
        the old state. The supports moved through it (lowered and raised again minutes apart).
        Its windows are left out (``Decision.moving``), as a ramp's are: taken as the old state's
        data, one such window 25 kN off pulled that level and the noise model, and the record's
        last state ended 8.7 mm off (``benchmarks/loadtest_days.py --only inside``, #7 of seed 0;
        #102: the run's mean within a vehicle's load, its one window between two steps 44 kN off
        on the sum, 4.3 mm). At most ``event_max_pending`` windows are held, and each left out is
        reported (``step_window``). The state itself is reported as a possible short change
        (``Decision.between_steps``), its level the mean of the windows beyond any vehicle (the
        others may hold a step for part of their length).

        One window beyond any vehicle that the data left the other way is such a run too: it did
        not come back, so it is no outlier (a short excursion that comes back), and no vehicle on
        the old state made it; the window two steps happened in, or a state shorter than a window
        between them (the reference record 51.8 h on, lowered 6.9 mm at minute 6 under the test
        car and raised 4.6 / 6.3 mm at minute 9, the car gone half a minute before: that window was
        an outlier, the one window of the lowered state the car left; ``--only inside
        --stream-seed 23``, #66). Within a vehicle's load it stays an outlier, as any one window.
        """
        *before, last = self.pending
        if len(before) == 1 and self._second_step_inside(before[0], last.v):
            self.pending = []
            return self._judged_again(Decision(moving=[before[0].payload]), last)
        if len(before) < 2 and not (before and self._beyond_any_vehicle(before[0].v)):
            return self._transient()
        self.pending = before
        cands = self._candidates()
        c = min(cands, key=lambda c: c.cost)
        if self._short_state(c):
            decision = self._unconfirmed(cands, provisional=True)
            decision.rejudge = [last.payload]
            return decision
        far = [p for p in self.pending if self._beyond_any_vehicle(p.v)]
        if far:  # neither level (see above); the state's level from the windows beyond any vehicle
            decision = Decision(
                moving=[p.payload for p in self.pending],
                excursion=[p.payload for p in far],
                excursion_n=np.mean([p.v for p in far], axis=0),
                excursion_cov_n2=self._mean_cov(far),
                between_steps=True,
            )
            self.left_k, self.left_level = self.pending[-1].k, decision.excursion_n
            self.pending = []
        else:
            decision = self._unconfirmed(cands, provisional=False)
        return self._judged_again(decision, last)

    def _judged_again(self, decision: Decision, last: Pending) -> Decision:
        """Return ``decision`` with the latest window ``last`` judged afresh (``step``) added."""
        again = self.step(
            last.k, tuple(last.v), _sym(last.r_window / self.inflation), _sym(last.apa), last.payload
        )
        decision.reject += again.reject
        decision.accept = again.accept
        return decision

    def _second_step_inside(self, item: Pending, level: np.ndarray) -> bool:
        """Whether ``item``, right after a state left out between two steps, held the second step.

        The state's windows were left out (``_moved_on``: ``left_k``, its level ``left_level``);
        the window after them lies between that level and ``level``, where the data went on (a
        window's innovation, or an event's step): the window the second step happened in, part of
        each level, as ``_event`` reads a window between two states. Not an outlier, which is a
        short excursion that comes back (the reference record 2.6 h on, lowered 5.3 mm at minute
        9 and raised 6.4 mm at minute 11, both steps inside windows: ``benchmarks/loadtest_days.py
        --only inside --stream-seed 71``, #272).
        """
        if item.k != self.left_k + 1:
            return False
        shifted = Pending(item.k, item.v - self.left_level, item.r_window, item.apa, None)
        return self._between(shifted, np.asarray(level) - self.left_level)

    def _event(self, c: _Candidate, split: tuple[int, int] | None = None) -> Decision:
        """Decide an event at ``c``'s change time, or after the ramp ``split`` (its windows moving)."""
        if split is None:
            before, moving, after, step = self.pending[: c.j], [], self.pending[c.j :], c.step
        else:
            before, moving, after, step = self._split_run(split)
        self.pending = []
        self.n_events += 1
        before, away = self._away_tail(before)
        if split is None and c.mixed and len(away) > 1 and self._between(away[-1], step):
            # the window that held part of the step, after held windows at another level (a drift):
            # neither state, not one of theirs (taken with them, it was data)
            level = np.mean([p.v for p in away[:-1]], axis=0)
            if self._d2(away[-1], level) > self.h_outlier:
                moving, away = away[-1:] + moving, away[:-1]
        change: list[Any] | None = None
        if len(away) == 1 and (self._between(away[0], step) or self._second_step_inside(away[0], step)):
            moving = away + moving  # the step happened inside it: it holds both states
        elif len(away) > 1:
            change = [p.payload for p in away]  # a state of its own before the event's
        else:
            before = before + away  # one odd window: an outlier, as any
        reject, ordinary = self._split_ordinary(before)
        self.prev = None  # innovations after the event refer to a new estimate
        return Decision(
            reject=[p.payload for p in reject],
            accept_before=ordinary,
            event=[p.payload for p in after],
            change=change,
            step_n=step,
            glr=c.glr,
            moving=[p.payload for p in moving],
        )

    def _away_tail(self, items: list[Pending]) -> tuple[list[Pending], list[Pending]]:
        """Split held windows before a change time into (the rest, the last ones beyond ``h_outlier``).

        The windows right before an event's change time that stayed away from the old state (none
        of them back within ``h_outlier``) did not come back: they are not outliers, which are
        short excursions that come back (``_event``).
        """
        n = len(items)
        while n and self._d2(items[n - 1], np.zeros(2)) > self.h_outlier:
            n -= 1
        return items[:n], items[n:]

    def _between(self, item: Pending, step: np.ndarray) -> bool:
        """Whether a window's innovation lies between no change and ``step`` (a step inside it)."""
        return 0.0 < self._fraction(item, step) < 1.0

    def _remember(self, k: int, v: Vec) -> None:
        """Keep an ordinary window's innovation for the ramp rule (the history restarts with ``prev``)."""
        if self.prev is None:
            self.history.clear()
        self.history.append((int(k), float(v[0]), float(v[1])))

    def _run_series(self) -> tuple[np.ndarray, np.ndarray, int]:
        """Return the remembered windows and the held run: innovations (n, 2), indices, count remembered."""
        h = len(self.history)
        y = np.array([x[1:] for x in self.history] + [p.v for p in self.pending], float).reshape(-1, 2)
        ks = np.array([x[0] for x in self.history] + [p.k for p in self.pending], np.int64)
        return y, ks, h

    def _split_run(
        self, split: tuple[int, int]
    ) -> tuple[list[Pending], list[Pending], list[Pending], np.ndarray]:
        """Return the held run around a ramp ``split``: before it, moving, the new state, its step."""
        after = self.pending[split[1] :]
        return (
            self.pending[: split[0]],
            self.pending[split[0] : split[1]],
            after,
            np.mean([p.v for p in after], axis=0),
        )

    def _ramp_split(self, series: tuple[np.ndarray, np.ndarray, int]) -> tuple[int, int] | None:
        """Return ``(first moving, first of the new state)`` in the held run when it holds a ramp.

        ``events.warmup.ramp_windows`` on the remembered ordinary windows and the held run (its
        false probability the trigger's). A support lowered over minutes moves the innovations
        a little in every window: the change time the run is most likely under falls inside
        the ramp, and the ramp's later windows, taken as the new state's, pulled its level (a
        20 mm lowering over eight minutes of continuous data read 15-17 mm). The ramp's
        windows are neither state; the new state begins after it.
        """
        y, ks, h = series
        found = ramp_windows(y, ks, self.false_trigger)
        if found is None or found[1] <= h:
            return None
        return max(found[0] - h, 0), found[1] - h

    def _unconfirmed(
        self,
        cands: list[_Candidate],
        provisional: bool,
        split: tuple[int, int] | None = None,
        drift: bool = False,
    ) -> Decision:
        """Decide a run that stayed away without qualifying: an unconfirmed change at its likeliest start.

        ``provisional`` (the run ends at the end of the data or at a gap): its windows start a
        provisional segment, weighed "changed" against "not changed" by the data (also after
        ``event_max_pending`` windows inside the data when the run moved far and clear:
        ``_forced``). Otherwise they are ordinary windows of the current segment, as a long
        excursion that is not a step is data, and the change is reported.
        With a ramp ``split``, the held windows right before it that were already away from the
        old state (beyond ``h_outlier``, as ``_away_tail`` reads them) move with it: taken as the
        old state's data, one such window 44 kN off (the test car leaving a state the run had
        just reached) pulled that state's level and the noise with it, and the next state ended
        9 mm off (``benchmarks/loadtest_days.py --only inside --stream-seed 7``, #199).
        """
        c = min(cands, key=lambda c: c.cost)
        common = {"step_n": c.step, "glr": c.glr, "step_cov_n2": self._step_cov(c)}
        if provisional and split is not None:  # a ramp: its windows neither state (``_ramp_split``)
            before, moving, after, common["step_n"] = self._split_run(split)
            before, away = self._away_tail(before)  # already away when the ramp began: moving too
            moving = away + moving
            self.pending = []
            self.prev = None
            payloads = ([p.payload for p in x] for x in (before, after, moving))
            ordinary, run, moved = payloads
            return Decision(accept_before=ordinary, change=run, moving=moved, **common)
        before, after = self.pending[: c.j], self.pending[c.j :]
        self.pending = []
        moved = []
        if provisional and c.mixed:  # the window before the change time held the step: neither state
            moved, before = [before[-1].payload], before[:-1]
        ordinary = [p.payload for p in before]  # a run that stayed away loses no window
        run = [p.payload for p in after]
        if provisional:
            self.prev = None  # innovations after the change refer to a new estimate
            return Decision(accept_before=ordinary, change=run, moving=moved, **common)
        self.prev = after[-1]
        return Decision(accept_before=ordinary + run, unconfirmed=run, drift=drift, **common)

    def _step_cov(self, c: _Candidate) -> np.ndarray:
        """Covariance (2, 2) N^2 of candidate ``c``'s step (the mean of its windows' innovations)."""
        return self._mean_cov(self.pending[c.j :])

    def _mean_cov(self, items: list[Pending]) -> np.ndarray:
        """Covariance (2, 2) N^2 of the mean innovation of held windows ``items`` (as consecutive)."""
        n = len(items)
        r_mean = np.mean([p.r_window for p in items], axis=0)
        f = ar1_factor(self.phi, n)  # V_j / n_j^2 of the GLR
        return np.sqrt(np.outer(f, f)) * r_mean / n + items[-1].apa

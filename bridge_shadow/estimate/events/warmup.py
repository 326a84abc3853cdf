"""A step among the warm-up windows: found before any noise model exists, so it is not fitted away.

The first ``warmup_windows`` windows are held until the curve and the noise model are first
fitted on them, and only then is the step detector (``detector``) run. A settlement inside those
windows (a node started minutes before a support is lowered; a short record, or one the test car
cut down, followed at once by the next) would be fitted as one state: the noise model takes the
step for noise, the curve bends through it, and no event is ever raised. So before the first fit
the held windows of each segment are searched for one step, on a scale they give themselves.

The test: the successive differences ``d_i = y_i - y_{i-1}`` of the window means (2,) N, each
over its lag (``warmup_step``); their robust covariance ``C`` (per channel
``(median |d| / 0.6745)^2``, the correlation by Gnanadesikan and Kettenring's identity
``cov(u, v) = (var(u + v) - var(u - v)) / 4`` on the standardized differences, each variance again
from the median); ``J_i = d_i' C^-1 d_i``. A step between two windows makes one large ``J``: it is a
step when it exceeds ``f`` times every other. A step inside a window makes two neighbouring large
``J`` of one sign: their sum is a step when its ``J`` exceeds ``f`` times every other but those
two. A passing excursion (one odd window) makes two of opposite signs, a drift many small ones.

Derivation of ``f`` (the argument of ``detector.JUMP_OVER_SEEN``): without a step the ``N``
values ``J_i`` are exchangeable, each ``c X`` with ``X`` chi-square(2) (exponential) and ``c``
whatever factor the robust scale is off by, which cancels. The single rule fires when the largest
exceeds ``f`` times the second: ``P1 = N Gamma(f + 1) Gamma(N) / Gamma(N + f)`` (the events for
each ``i`` are disjoint, each ``E[U^f]`` with ``U`` the minimum of ``N - 1`` uniforms). The pair
rule fires at most when the two largest together exceed ``f`` times the third (a pair's ``J`` is
at most the sum of its two, Cauchy-Schwarz): ``P2``, one integral over the third largest
(``false_step_probability``). ``f`` makes ``P1 + P2`` the per-window false-alarm probability of
the detector's trigger (``1 - event_trigger_probability``): with the default 1e-3, ``f = 15.6`` for
ten windows (nine differences), 33 for seven, 187 for five, 6000 for four, and no step is looked
for in fewer than four windows (the median of two differences is half the step itself). A 10 mm
lowering of this bridge moves the window means by 20-40 kN against jumps of 0.1-3 kN between
ordinary one-minute windows: ``J`` ratios of 50 to 1e5. The covariance read from a few
differences makes the tails of ``J`` heavier than chi-square(2): on AR(1) noise of ten windows the
rate measured at the default is 0.035 % (phi 0) to 0.37 % (phi 0.99, a random walk), at 1 % 0.16 %
to 1.24 % (``test_warmup_step``).

Two steps of one size hide each other from that rule (neither is ``f`` times the other): a support
lowered twice within a record, each state kept by the traffic screen. ``warmup_steps`` then asks
the smaller of the two jumps (each a difference or a pair of neighbours) and their sum to beat
``two_step_ratio`` times every other difference, its false probability bounded the same way
(``false_two_step_probability``; 17.8 for twelve differences at the default, 32.7 for nine). On
AR(1) noise of ten windows it adds at most 0.03 % to the one-step rule's rate at the default.

What is found is not declared an event: it opens a *provisional* segment there (as a gap does,
``change_prior_probability``), and the data after it decide, by the same weighing of "changed"
against "not changed" (``settlement.segments``), whether it becomes an event. A false split costs
an unconfirmed change of low probability, never a window.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from functools import lru_cache

import numpy as np
from scipy import integrate, optimize, special

__all__ = [
    "HOLD_MOVING_DIFFERENCES",
    "MIN_DIFFERENCES",
    "RAMP_HOLD_FACTOR",
    "beyond_any_vehicle",
    "false_ramp_probability",
    "false_step_probability",
    "false_two_step_probability",
    "jump_goes_on",
    "level_beyond_vehicle_at_last",
    "lone_windows_beyond_vehicle",
    "moved_not_still",
    "moved_then_still",
    "moving_on_known_noise",
    "new_state_at_last",
    "over_median_ratio",
    "ramp_beyond_vehicle_at_last",
    "ramp_in_progress",
    "ramp_ratio",
    "ramp_windows",
    "step_ratio",
    "step_windows",
    "two_step_ratio",
    "warmup_step",
    "warmup_steps",
]

#: Fewer successive differences than this are not searched (see the module docstring).
MIN_DIFFERENCES = 3
#: Cap on the robust correlation of the two channels' differences (see ``_robust_precision``).
MAX_CORRELATION = 0.9
#: A ramp spans at least this many differences (two or fewer are the step rules'), and leaves at
#: least this many outside it (the states before and after, and the scale it is measured against).
RAMP_MIN_LENGTH = 3
RAMP_MIN_REST = 2
#: A ramp's inner windows each move at least this share of its mean speed (``_ramp_score``):
#: a jack lowering a support moves it in every minute, at a speed that varies (a quarter: a
#: choice, set after the two-step streams of the real records showed a state kept for minutes
#: between two steps, its car drifting 1 kN a minute, read as a ramp at a tenth of the mean).
RAMP_MIN_SPEED = 0.25
#: Windows after a gap are held on while a ramp is in progress, up to this many times
#: ``warmup_windows`` (a lowering record of 2022-04-11 lasts 18 to 30 minutes by the day's
#: temperature files; 30 one-minute windows; a drift that never ends is released then, as before).
RAMP_HOLD_FACTOR = 3
#: Successive differences that must each move beyond the noise known before a gap for the windows
#: after it to be held on (``moving_on_known_noise``): one more than a step inside a window (two
#: differences of one sign) and a vehicle driving on right after it can make. With three, two
#: settlements inside a record read a third event on one stream of 300 (`--only inside
#: --stream-seed 7`, #66).
HOLD_MOVING_DIFFERENCES = RAMP_MIN_LENGTH + 1
#: Median of |N(0, 1)|: a robust standard deviation is ``median |x| / MAD_NORMAL``.
MAD_NORMAL = 0.6744897501960817


@lru_cache(maxsize=4096)
def _log_order_norm(m: int, n: int) -> float:
    """``log(n! / ((m-1)! (n-m)!))``: the constant of ``_log_order_density``, once per ``(m, n)``.

    The integrals below evaluate the density thousands of times at one ``(m, n)``; its three
    ``gammaln`` calls were half of each evaluation (the same value, hence the same density).
    """
    return special.gammaln(n + 1.0) - special.gammaln(float(m)) - special.gammaln(n - m + 1.0)


def _log_order_density(x: float, m: int, n: int) -> float:
    """Log density at ``x > 0`` of the ``m``-th largest of ``n`` unit exponentials.

    ``n! / ((m-1)! (n-m)!) (1 - e^-x)^(n-m) e^(-m x)``.
    """
    return float(_log_order_norm(m, n) + (n - m) * np.log(-np.expm1(-x)) - m * x)


def false_step_probability(f: float, n: int) -> float:
    """Return the false-step probability of the rule with ratio ``f`` over ``n`` differences (a bound).

    ``n`` exchangeable exponential ``J`` (chi-square(2) up to one scale): the largest beats ``f``
    times every other (``P1``, exact), or the two largest together beat ``f`` times the third
    (``P2``: a pair of neighbours counts as one jump, and its ``J`` is at most the sum of theirs).
    """
    if n < 3:
        return 1.0
    p1 = np.exp(np.log(n) + special.gammaln(f + 1.0) + special.gammaln(n) - special.gammaln(n + f))
    # P2: given the third largest x, the two above it exceed x by two unit exponentials (memoryless),
    # whose sum G is Gamma(2): P(2x + G > f x) = (1 + c x) exp(-c x), c = f - 2, averaged over the
    # density of the third largest of n unit exponentials.
    c = f - 2.0
    if c <= 0:
        return 1.0

    def integrand(x: float) -> float:
        if x <= 0:
            return 0.0
        return (1.0 + c * x) * np.exp(_log_order_density(x, 3, n) - c * x)

    p2, _ = integrate.quad(integrand, 0.0, np.inf, limit=200)
    return float(min(p1 + p2, 1.0))


def _ratio_for(
    false_probability: Callable[[float, int], float], n: int, probability: float, lo: float
) -> float:
    """Return the ratio ``f`` (above ``lo``) at which ``false_probability(f, n)`` is ``probability``.

    ``lo`` itself where its false probability is already at most ``probability`` (the bound
    decreases in ``f``, so the rule at ``lo`` keeps it): a ramp of nearly every difference, whose
    one-sign condition alone is that improbable (``false_ramp_probability``; a jack lowering a
    support over 20 of 26 one-minute windows held after a gap raised ValueError here).
    """
    if false_probability(lo, n) <= probability:
        return float(lo)
    hi = 2.0 * lo
    while false_probability(hi, n) > probability:
        lo, hi = hi, hi * 2.0
        if hi > 1e7:
            return float("inf")
    return float(optimize.brentq(lambda f: false_probability(f, n) - probability, lo, hi, xtol=1e-6))


@lru_cache(maxsize=256)
def step_ratio(n: int, probability: float) -> float:
    """Return the ratio ``f`` whose false-step probability over ``n`` differences is ``probability``."""
    return _ratio_for(false_step_probability, n, probability, 2.0)


def _second_over(g: float, m: int, n: int) -> float:
    """``P(second largest > g x m-th largest)`` for ``n`` unit exponentials (0 when ``n < m``).

    Given the ``m``-th largest ``x``, the ``m - 1`` above it are ``x`` plus independent unit
    exponentials (memoryless); at least two of them exceed ``g x`` with probability
    ``1 - (1 - q)^(m-1) - (m - 1) q (1 - q)^(m-2)``, ``q = exp(-(g - 1) x)``, averaged over the
    density of the ``m``-th largest (``_log_order_density``).
    """
    if n < m:
        return 0.0
    if g <= 1.0:
        return 1.0

    def integrand(x: float) -> float:
        if x <= 0:
            return 0.0
        q = np.exp(-(g - 1.0) * x)
        two = 1.0 - (1.0 - q) ** (m - 1) - (m - 1) * q * (1.0 - q) ** (m - 2)
        return float(two * np.exp(_log_order_density(x, m, n)))

    p, _ = integrate.quad(integrand, 0.0, np.inf, limit=200)
    return float(min(max(p, 0.0), 1.0))


def false_two_step_probability(f: float, n: int) -> float:
    """Return a bound of the two-step rule's false probability over ``n`` differences (``warmup_steps``).

    Without a step the ``n`` values ``J`` are exchangeable exponentials up to one scale. Two single
    differences beating ``f`` times every other: the second largest beats ``f`` times the third.
    A step inside a window is a pair of neighbours, its jump's ``J`` at most the sum of theirs
    (``(u + v)' P (u + v) / 2 <= u' P u + v' P v``, lag-weighted alike), so a pair and a single
    (three differences left out) beating ``f`` times the rest need two values above ``f / 2`` times
    the fourth largest, and two pairs two above ``f / 2`` times the fifth. The bound is the sum of
    the three (``_second_over``); the rule also asks the two jumps' sum to beat it.
    """
    if n < 3:
        return 1.0
    total = _second_over(f, 3, n) + _second_over(f / 2.0, 4, n) + _second_over(f / 2.0, 5, n)
    return float(min(total, 1.0))


@lru_cache(maxsize=256)
def two_step_ratio(n: int, probability: float) -> float:
    """Return the ratio ``f`` whose two-step false probability over ``n`` differences is ``probability``."""
    if n < 3:
        return float("inf")
    return _ratio_for(false_two_step_probability, n, probability, 2.0)


def beyond_any_vehicle(step: np.ndarray | tuple[float, float], vehicle_max_n: float) -> bool:
    """Whether ``step`` (2,) N moved the reactions' sum by more than any vehicle, either way.

    ``vehicle_max_n`` is the traffic screen's ``traffic_vehicle_max_n``: more than a vehicle adds,
    or more than one leaving takes off an estimate made while it stood.
    """
    return abs(float(step[0] + step[1])) > vehicle_max_n


def lone_windows_beyond_vehicle(y: np.ndarray, vehicle_max_n: float) -> list[int]:
    """Return the indices of windows alone beyond any vehicle that came back, among ``y`` (n, 2) N.

    Window ``i`` jumps from window ``i - 1`` and back into window ``i + 1``, each by more than any
    vehicle (``beyond_any_vehicle``, opposite ways), and ``i + 1`` is within a vehicle of
    ``i - 1``: a load no vehicle adds that stood one window (a glitch, a load that stopped for a
    minute), or a settlement undone a window later, which no support does. One window alone is
    no state (``events.detector.SHORT_STATE_WINDOWS``): an outlier, as the detector rejects one.
    """
    s = np.asarray(y, float).reshape(-1, 2).sum(axis=1)
    out = []
    for i in range(1, len(s) - 1):
        up, back = s[i] - s[i - 1], s[i + 1] - s[i]
        if abs(up) > vehicle_max_n and abs(back) > vehicle_max_n and up * back < 0.0:
            if abs(s[i + 1] - s[i - 1]) <= vehicle_max_n:
                out.append(i)
    return out


def warmup_steps(
    y: np.ndarray, k: np.ndarray, probability: float, vehicle_max_n: float = math.inf
) -> list[int]:
    """Return the indices of the first windows after every step in window means ``y`` (n, 2) N.

    ``step_windows`` without the windows the steps happened in.
    """
    return [start for start, _ in step_windows(y, k, probability, vehicle_max_n)]


def step_windows(
    y: np.ndarray, k: np.ndarray, probability: float, vehicle_max_n: float = math.inf
) -> list[tuple[int, int | None]]:
    """Return ``(first window of the new state, window the step happened in or None)`` per step.

    A settlement may come in stages (a support lowered twice within minutes: a record the traffic
    screen keeps in three states). ``warmup_step`` finds one step that dwarfs every other
    difference. Two steps of comparable size hide each other from that rule (the largest is not
    ``f`` times the second): they are two steps when the smaller of their ``J`` beats
    ``two_step_ratio`` times every other difference's (derived as ``step_ratio``: the same
    false-step probability for noise alone; a step inside a window is two neighbouring differences
    of one sign, counted as one jump as in ``warmup_step``), with at least one window between them,
    and their sum beats it too (a vehicle that stayed a few windows and left makes two large jumps
    that cancel: an excursion, not two steps), unless the first moves the reactions' sum by more
    than any vehicle (``vehicle_max_n``, N, the traffic screen's ``traffic_vehicle_max_n``, either
    way): a support lowered and raised again minutes later, the state between held for minutes, is
    two steps however near the second brings the reactions back (the rule's bound does not rest on
    the sum: it only makes the rule stricter). A false split costs an unconfirmed change the data
    merge back (see the module docstring). The window a step happened in (two neighbouring
    differences of one sign) holds both states: returned with the step (``_mixed_start`` gives which
    side it is nearer, the first window of the new state or the last of the old) when both its
    neighbours are next to it; with windows missing around it (cut by the traffic screen) it may be
    a short state of its own, and None is returned for it.
    """
    k = np.asarray(k, np.int64).reshape(-1)
    found = _steps(y, k, probability, vehicle_max_n)
    return [(s, m if m is not None and k[m + 1] - k[m - 1] == 2 else None) for s, m in found]


def _steps(
    y: np.ndarray, k: np.ndarray, probability: float, vehicle_max_n: float
) -> list[tuple[int, int | None]]:
    """``step_windows`` before the check of the mixed windows' neighbours."""
    one = _one_step(y, k, probability)
    if one is not None:
        return [one]
    diffs = _differences(y, k, MIN_DIFFERENCES + 1)
    if diffs is None:
        return []
    raw, lag, _, prec, single = diffs
    m = len(raw)

    def score(idx: list[int]) -> float:  # J of one jump over the differences idx
        d = raw[idx].sum(axis=0) / np.sqrt(lag[idx].sum())
        return float(d @ prec @ d)

    # a jump's J is at most twice its largest difference's, and must beat f (> 2) times every
    # difference left out: each jump holds one of the four largest (at most four are left out),
    # and the second largest beats f / 2 times the fifth
    f = two_step_ratio(m, probability)
    ranked = np.sort(single)
    if m >= 5 and ranked[-2] <= 0.5 * f * ranked[-5]:
        return []
    top = set(np.argsort(single)[-4:].tolist())
    jumps = []  # (first difference, last difference, J, first window of the new state, mixed window)
    for a in range(m):
        if a in top:
            jumps.append((a, a, single[a], a + 1, None))
        if a + 1 < m and top & {a, a + 1} and float(raw[a] @ prec @ raw[a + 1]) > 0.0:
            jumps.append((a, a + 1, score([a, a + 1]), _mixed_start(raw, a), a + 1))
    best, found = 0.0, []
    for p, q in itertools.combinations(jumps, 2):
        if p[1] + 1 >= q[0]:
            continue  # overlapping or adjacent: one step, or an odd window
        both = [*range(p[0], p[1] + 1), *range(q[0], q[1] + 1)]
        rest = np.delete(single, both)
        if not len(rest):
            continue
        first = raw[p[0] : p[1] + 1].sum(axis=0)  # an excursion a vehicle makes, or the first of two steps
        jump = min(p[2], q[2]) if beyond_any_vehicle(first, vehicle_max_n) else min(p[2], q[2], score(both))
        ratio = jump / max(float(np.max(rest)), 1e-300)
        if ratio > f and ratio > best:
            best, found = ratio, [(p[3], p[4]), (q[3], q[4])]
    return found


def new_state_at_last(y: np.ndarray, k: np.ndarray, probability: float, vehicle_max_n: float) -> bool:
    """Whether the last of window means ``y`` (n, 2) N begins a state no vehicle and no noise makes.

    Its jump (the last difference, or the last two when they share a sign: a step inside the
    window before) moves the reactions' sum beyond any vehicle (``vehicle_max_n``, either way),
    and its ``J`` (``_differences``) exceeds ``c`` times the (lower) median ``J`` of the differences
    before it, ``c = over_median_ratio(m, probability / 2)`` for each of the two jumps: without a step
    the ``J`` are exchangeable, each the robust scale's error times a chi-square(2), which cancels
    in the ratio. Unlike the step rules it does not ask the jump to dwarf every other difference:
    a load that stood over several of the windows, coming and going in stages, makes differences
    of a vehicle's size that hide a settlement from those rules; no vehicle makes this jump.
    """
    diffs = _differences(y, k, MIN_DIFFERENCES)
    if diffs is None:
        return False
    raw, lag, _, prec, single = diffs
    half = 0.5 * probability
    jumps = [(raw[-1], float(single[-1]), single[:-1])]
    if len(raw) > MIN_DIFFERENCES and float(raw[-1] @ prec @ raw[-2]) > 0.0:
        d = (raw[-1] + raw[-2]) / np.sqrt(lag[-1] + lag[-2])
        jumps.append((raw[-1] + raw[-2], float(d @ prec @ d), single[:-2]))
    return any(
        beyond_any_vehicle(step, vehicle_max_n)
        and j > over_median_ratio(len(rest), half) * float(np.sort(rest)[(len(rest) - 1) // 2])
        for step, j, rest in jumps
    )


@lru_cache(maxsize=256)
def over_median_ratio(m: int, probability: float) -> float:
    """Return ``c`` with ``P(X > c M) = probability``, ``M`` the median of ``m`` others (i.i.d. exponential).

    Rényi's representation of the ``r``-th smallest of ``m`` exponentials,
    ``sum_{i <= r} E_i / (m - i + 1)``, gives ``P(X > c M) = E[exp(-c M)] =
    prod_{i <= r} (m - i + 1) / (m - i + 1 + c)`` (``r = ceil(m / 2)``, the lower median).
    """
    r = (m + 1) // 2

    def excess(c: float) -> float:
        return float(np.prod([(m - i + 1) / (m - i + 1 + c) for i in range(1, r + 1)])) - probability

    return float(optimize.brentq(excess, 0.0, 1e12))


def jump_goes_on(y: np.ndarray, k: np.ndarray, probability: float) -> bool:
    """Whether the last difference of window means ``y`` (n, 2) N goes on the jump before it.

    The two share a sign (``d_a' P d_b > 0``, ``P`` the differences' robust precision) and the
    last one's ``J`` is above the chi-square(2) quantile of ``probability``, the robust scale taken
    as right: asked only of a jump ``new_state_at_last`` found (``Shadow._young_first``), whether
    the window after it moved on the same way, so the window between them is where the jump
    happened, holding both states.
    """
    diffs = _differences(y, k, MIN_DIFFERENCES)
    if diffs is None:
        return False
    _, _, d, prec, single = diffs
    return float(d[-2] @ prec @ d[-1]) > 0.0 and float(single[-1]) > -2.0 * math.log(probability)


def false_ramp_probability(f: float, n: int, length: int, blocks: int | None = None) -> float:
    """Return a bound of the false probability of the ramp rule for blocks of ``length`` of ``n`` differences.

    Without a change the differences are increments of the noise, each ``J_i`` an exponential up
    to one scale (as for the step rules), symmetric about zero. The block's sum over its lag has
    ``J`` at most the sum of the block's ``J_i`` (Cauchy-Schwarz, lag-weighted), so beating ``f``
    times the largest ``M_r`` of the ``r = n - length`` others needs ``sum J_i > f M_r``: a
    Gamma(``length``) against ``f`` times the largest of ``r`` unit exponentials. The one-sign
    condition (each ``d_i' P s > 0``, ``s`` the sum) is a sign pattern of the ``d_i``, independent
    of their magnitudes by symmetry; as ``s`` turns once round, the pattern ``sign(d_i' P s)``
    changes at ``2 length`` directions, so at most ``2 length`` of the ``2^length`` patterns can
    hold it. Per block the bound is the product, or, without the signs, the block's own ``J``
    (exponential itself for a random walk) beating ``f M_r``: ``Gamma(f + 1) r! / Gamma(r + f + 1)``,
    whichever is smaller; summed over the ``blocks`` tried (default all
    ``n - length + 1``; one for a block ending at the last difference, ``ramp_in_progress``), a
    union bound. The independence of a block from the rest is a random walk's (AR(1) with ``phi``
    near 1); for smaller ``phi`` the increments cancel in the sum and the rule fires less.
    """
    r = n - length
    if r < 1 or length < 1:
        return 1.0
    count = n - length + 1 if blocks is None else blocks

    def integrand(x: float) -> float:  # P(Gamma(length) > f x) times the density of M_r at x
        if x <= 0:
            return 0.0
        return float(special.gammaincc(length, f * x) * np.exp(_log_order_density(x, 1, r)))

    tail, _ = integrate.quad(integrand, 0.0, np.inf, limit=200)
    signs = min(2.0 * length * 0.5**length, 1.0)
    # the block's own J against the rest (an exponential itself for a random walk), without the signs
    alone = np.exp(special.gammaln(f + 1.0) + special.gammaln(r + 1.0) - special.gammaln(r + f + 1.0))
    return float(min(count * min(signs * tail, alone), 1.0))


@lru_cache(maxsize=1024)
def ramp_ratio(n: int, length: int, probability: float, open_end: bool = False) -> float:
    """Return the ratio ``f`` whose ramp false probability (``length`` of ``n``) is ``probability``.

    ``ramp_windows`` tries every block length from ``RAMP_MIN_LENGTH`` to ``n - RAMP_MIN_REST``
    (``open_end``: only the block ending at the last difference, ``ramp_in_progress``); the
    probability allowed is shared equally among the lengths.
    """
    lengths = max(n - RAMP_MIN_REST - RAMP_MIN_LENGTH + 1, 1)
    share = probability / lengths
    blocks = 1 if open_end else None
    return _ratio_for(lambda f, m: false_ramp_probability(f, m, length, blocks), n, share, 2.0)


def _ramp_score(
    raw: np.ndarray,
    lag: np.ndarray,
    prec: np.ndarray,
    single: np.ndarray,
    block: tuple[int, int],
    probability: float,
    open_end: bool = False,
) -> float:
    """Return how many times its ``ramp_ratio`` the block of differences ``block = (a, b)`` beats, or 0.

    The block ``raw[a:b]`` (its first and last may be partial windows of the ramp; with
    ``open_end`` it ends at the last difference, a ramp still going on, and its last is inner) is a
    ramp when (``ramp_windows``):

    - every difference lies on one side along the block's sum ``s`` (``d_i' P s > 0``): an
      excursion, a car or noise has both;
    - it moved in every inner window: each inner difference larger in ``J`` than every difference
      outside the block, and along ``s`` at least ``RAMP_MIN_SPEED`` of the block's mean (one that
      stood still between two steps is states, which the step rules and the detector read);
    - it is more than one step: without its largest difference it still beats the ratio (a step
      with a noise difference of its sign on either side moved in its one inner window; taken for a
      ramp, the new state's first window was left out on every confirmed step in the detector's
      tests); a ramp's rest still moved, a step's is noise, which beats it no more often than the
      rule's derived false probability;
    - its sum over its lag beats ``ramp_ratio`` times the largest difference outside it.
    """
    a, b = block
    m = len(raw)
    d, lags, j = raw[a:b], lag[a:b], single[a:b]
    total = d.sum(axis=0)
    along = d @ prec @ total
    if not np.all(along > 0.0):
        return 0.0
    top = max(float(np.max(np.concatenate([single[:a], single[b:]]))), 1e-300)
    inner = slice(1, None) if open_end else slice(1, -1)
    if len(j[inner]) and (
        np.min(j[inner]) <= top or np.min(along[inner]) < RAMP_MIN_SPEED * float(np.mean(along))
    ):
        return 0.0
    keep = np.arange(len(d)) != int(np.argmax(j))
    rest = d[keep].sum(axis=0)
    if (
        float(rest @ prec @ rest) / float(lags[keep].sum())
        <= ramp_ratio(m, int(keep.sum()), probability) * top
    ):
        return 0.0
    f = ramp_ratio(m, b - a, probability, open_end)
    ratio = float(total @ prec @ total) / float(lags.sum()) / top
    return ratio / f if ratio > f else 0.0


def ramp_in_progress(y: np.ndarray, k: np.ndarray, probability: float) -> bool:
    """Whether the last windows of ``y`` (n, 2) N are a ramp that has not ended (``ramp_windows``).

    The test of ``ramp_windows`` for the blocks that end at the last difference, their states
    before them only: the windows held after a gap are then held on (``Shadow``) until the
    ramp ends, so that the state after it has windows of its own.
    """
    diffs = _differences(y, k, RAMP_MIN_LENGTH + RAMP_MIN_REST)
    if diffs is None:
        return False
    raw, lag, _, prec, single = diffs
    m = len(raw)
    return any(
        _ramp_score(raw, lag, prec, single, (m - length, m), probability, open_end=True) > 0.0
        for length in range(RAMP_MIN_LENGTH, m - RAMP_MIN_REST + 1)
    )


def ramp_beyond_vehicle_at_last(
    y: np.ndarray, k: np.ndarray, probability: float, vehicle_max_n: float
) -> int | None:
    """Return the first moving window of a ramp going on at the last of ``y`` (n, 2) N that no vehicle makes.

    Among the blocks of ``ramp_in_progress`` (on the windows' own scale, ending at the last
    difference) those whose last window moved the reactions' sum beyond any vehicle
    (``vehicle_max_n``, either way) from the window before the block: a support lowered over
    minutes, where no one difference is a jump for ``new_state_at_last``. The block with the
    largest ratio is taken (as ``ramp_windows`` does); None without one. The ramp's bound
    (``ramp_ratio``) holds its false probability; the vehicle bound adds that no load driving onto
    the bridge moves the reactions so far.
    """
    y = np.asarray(y, float).reshape(-1, 2)
    s = y.sum(axis=1)
    if not np.any(np.abs(s[-1] - s[:-RAMP_MIN_LENGTH]) > vehicle_max_n):
        return None  # the last window is within any vehicle of every window a block could start at
    diffs = _differences(y, k, RAMP_MIN_LENGTH + RAMP_MIN_REST)
    if diffs is None:
        return None
    raw, lag, _, prec, single = diffs
    m = len(raw)
    scores = {  # by the block's first moving window, shortest block first
        m - length + 1: _ramp_score(raw, lag, prec, single, (m - length, m), probability, open_end=True)
        for length in range(RAMP_MIN_LENGTH, m - RAMP_MIN_REST + 1)
        if beyond_any_vehicle(y[-1] - y[m - length], vehicle_max_n)
    }
    first = max(scores, key=scores.__getitem__, default=None)
    return first if first is not None and scores[first] > 0.0 else None


def level_beyond_vehicle_at_last(
    y: np.ndarray, vehicle_max_n: float, raises: bool = True
) -> tuple[int, int] | None:
    """Return ``(first window moving, first window of the new level)`` of a level the last windows hold.

    The reactions' sum ``s`` of ``y`` (n, 2) N is fitted, by least squares, as a level ``L0`` up to
    window ``a``, a straight line from ``L0`` to ``L1`` over windows ``a .. b - 1`` (none: a step),
    and ``L1`` from ``b`` on (the old state, a support lowered over minutes, the new state), for
    every ``a`` and ``b`` that leave at least ``RAMP_MIN_REST + 1`` windows to either level; the
    best fit is a change when ``RAMP_MIN_REST + 1`` of the windows from ``b`` on lie beyond any
    vehicle (``vehicle_max_n``) below every window before ``a`` (a lowering: no old window is the
    new state with a vehicle on it), or when their mean lies beyond it above every one of them (a
    raise: the new level is no old state with a vehicle on it). A vehicle only adds load: one
    parked over the first minutes of the data and gone, with the test car's +9 kN on the other
    side, moved the old windows' mean by more than the bound, but not their lowest; one parked on
    a share of the new level's windows lifts their mean by that share of its load (the helper's
    streams with 30 kN over minutes 2-4 and 10 mm at minute 12: the test car's plateaus on the new
    level held its mean within twice the bound below the old level's lowest window), but not its
    lowest windows, which
    a lowering is read from; a raise is read from the mean, which such a vehicle lifts, so that
    the windows it loads count no more than their share (``raises=False``: lowerings only).
    A ramp whose pace the test car's moves break is no ramp for ``ramp_windows`` and no jump for
    ``new_state_at_last``; a ramp still going on fits best with its line to the last window, or
    leaves windows after ``b`` that go on its way at ``RAMP_MIN_SPEED`` of its speed or more (the
    slope of their own line), so the new level is read only once it has ``RAMP_MIN_REST + 1``
    windows that have stopped. No probability is asked of the noise: the bound is the loads',
    and a level a heavier load held is a provisional change the data after it decide, as any
    step rule's.
    """
    s = np.asarray(y, float).reshape(-1, 2).sum(axis=1)
    n, least = len(s), RAMP_MIN_REST + 1
    if n < 2 * least or not np.all(np.isfinite(s)):
        return None
    # the old level holds the first windows and the new level's mean lies among later ones: with no
    # later window beyond any vehicle from them either way there is nothing to fit (most windows)
    head, rest = s[:least], s[least:]
    if (
        float(np.min(rest)) >= float(np.min(head)) - vehicle_max_n
        and float(np.max(rest)) <= float(np.max(head)) + vehicle_max_n
    ):
        return None
    j = np.arange(n, dtype=float)
    pairs = [(a, b) for a in range(least, n - least + 1) for b in range(a, n + 1)]
    ab = np.array(pairs, float)
    # share of the new level in each window: 0 before a, rising over a .. b - 1, 1 from b
    f = np.clip((j[None, :] - ab[:, :1] + 1.0) / (ab[:, 1:] - ab[:, :1] + 1.0), 0.0, 1.0)
    g = 1.0 - f
    s00, s01, s11 = (g * g).sum(axis=1), (g * f).sum(axis=1), (f * f).sum(axis=1)
    r0, r1 = g @ s, f @ s
    det = s00 * s11 - s01 * s01
    ok = det > 0.0
    l0 = np.where(ok, (s11 * r0 - s01 * r1) / np.where(ok, det, 1.0), np.nan)
    l1 = np.where(ok, (s00 * r1 - s01 * r0) / np.where(ok, det, 1.0), np.nan)
    sse = ((s[None, :] - g * l0[:, None] - f * l1[:, None]) ** 2).sum(axis=1)
    best = int(np.nanargmin(np.where(ok, sse, np.nan)))
    first, start = pairs[best]
    if n - start < least:
        return None  # still moving, or the new level has too few windows yet
    speed = float(l1[best] - l0[best]) / (start - first + 1)
    if float(np.polyfit(j[start:], s[start:], 1)[0]) * math.copysign(1.0, speed) >= RAMP_MIN_SPEED * abs(
        speed
    ):
        return None  # the new level's windows go on the way the ramp went: it has not ended
    # a lowering: RAMP_MIN_REST + 1 of the new level's windows beyond the bound below every old one
    # (a vehicle only adds load: the lowest windows are the ones free of vehicles, and those it
    # loads cannot hide the level; one odd low window is not a level); a raise: their mean above
    # every old one (the windows a vehicle loads lift it: no order statistic lets them count more)
    old, new = s[:first], s[start:]
    if float(np.sort(new)[least - 1]) < float(np.min(old)) - vehicle_max_n:
        return first, start
    if raises and float(np.mean(new)) > float(np.max(old)) + vehicle_max_n:
        return first, start
    return None


def level_unsettled_at_last(y: np.ndarray, vehicle_max_n: float) -> bool:
    """Whether the last of ``y`` (n, 2) N lies beyond any vehicle below every one of the first windows.

    The reactions' sum of the last window below the lowest of the first ``RAMP_MIN_REST + 1``
    windows by more than ``vehicle_max_n``: a lowering ``level_beyond_vehicle_at_last`` may read
    once it has ``RAMP_MIN_REST + 1`` windows at rest (those windows beyond twice the bound below
    every old window need the last one beyond the bound below the first ones, give or take the
    noise: a necessary condition with that margin). A raise is not asked for: a vehicle parked on
    a smaller raise makes one (``Shadow._level_unsettled``).
    """
    s = np.asarray(y, float).reshape(-1, 2).sum(axis=1)
    least = RAMP_MIN_REST + 1
    if len(s) < 2 * least or not np.all(np.isfinite(s)):
        return False
    return bool(s[-1] < s[:least].min() - vehicle_max_n)


def _known_noise_moves(
    y: np.ndarray, k: np.ndarray, window_cov: np.ndarray, phi: np.ndarray, probability: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]:
    """Differences of ``y`` read against a known noise: ``d`` (m, 2), ``lag`` (m,), ``J`` (m,), cov, ``q``.

    ``J = d' S^-1 d``, ``S`` the AR(1) difference covariance ``2 (1 - phi^lag) o window_cov``
    (chi-square(2) without a change); ``q`` the level each of ``HOLD_MOVING_DIFFERENCES`` of them
    must pass (``moving_on_known_noise``).
    """
    n_l = HOLD_MOVING_DIFFERENCES
    q = 2.0 * math.log(2.0 * n_l * 0.5**n_l / probability)
    k = np.asarray(k, np.int64).reshape(-1)
    d = np.diff(np.asarray(y, float).reshape(-1, 2), axis=0)
    lag = np.diff(k).astype(float)
    phi = np.clip(np.asarray(phi, float).reshape(2), 0.0, 0.999)
    cov = np.asarray(window_cov, float).reshape(2, 2)
    js = np.empty(len(d))
    for i, (di, li) in enumerate(zip(d, lag, strict=True)):
        f = np.sqrt(2.0 * (1.0 - phi**li))
        js[i] = float(di @ np.linalg.solve(cov * np.outer(f, f), di))
    return d, lag, js, cov, q


def _moved_block(d: np.ndarray, lag: np.ndarray, js: np.ndarray, cov: np.ndarray, q: float, end: int) -> bool:
    """Whether the ``HOLD_MOVING_DIFFERENCES`` differences ending at ``end`` moved (see the hold)."""
    block = slice(end - HOLD_MOVING_DIFFERENCES, end)
    if block.start < 0 or min(js[block]) <= q:
        return False
    total = d[block].sum(axis=0)
    speed = d[block] @ np.linalg.solve(cov, total) / lag[block]
    return bool(speed.min() > 0.0 and speed.min() >= RAMP_MIN_SPEED * speed.mean())


def moving_on_known_noise(
    y: np.ndarray, k: np.ndarray, window_cov: np.ndarray, phi: np.ndarray, probability: float
) -> bool:
    """Whether ``HOLD_MOVING_DIFFERENCES`` successive differences ending at the last or the one before moved.

    Read against a known noise (the noise model fitted before a gap), not against differences of
    ``y`` itself: each difference ``d`` of windows ``lag`` apart has ``J = d' S^-1 d``, ``S`` the
    AR(1) difference covariance ``2 (1 - phi^lag) o window_cov``, chi-square(2) without a change.
    Moved: every ``J`` beyond ``q``, and each of one sign along their sum, moving per window of
    its lag at least ``RAMP_MIN_SPEED`` of their mean (at a pace, as in ``_ramp_score``: a step
    inside a window and a vehicle driving on after it are no ramp). Without a change the signs
    are a pattern independent of the sizes (as in ``false_ramp_probability``), at most
    ``2 L / 2^L`` of them of one sign (``L`` the differences), and any one ``J`` beyond ``q`` has
    ``exp(-q / 2)``: ``q`` is
    set so that the product is ``probability`` (a bound: on AR(1) noise of the model none of
    4,000 draws was held at 1 %, at phi 0, 0.5 and 0.95). Ending one difference before the last as well,
    the windows are held one more: ``ramp_windows`` then has two differences of the state after.
    """
    d, lag, js, cov, q = _known_noise_moves(y, k, window_cov, phi, probability)
    return any(_moved_block(d, lag, js, cov, q, end) for end in (len(d), len(d) - 1))


def moved_then_still(
    y: np.ndarray,
    k: np.ndarray,
    window_cov: np.ndarray,
    phi: np.ndarray,
    probability: float,
    vehicle_max_n: float,
    one_sign: bool = True,
) -> tuple[int, int] | None:
    """Return ``(first window moving, first window of the new state)`` of windows that moved and stopped.

    Where neither step rule nor ``ramp_windows`` reads windows held after a gap, a change the
    hold saw (``moving_on_known_noise``) is still a change when it stopped: jacks that lowered
    a support in stages, a few millimetres at a time with holds between (no window dwarfs the
    others, and the holds break the ramp's pace), or a ramp whose pace the test car's moves
    broke. Read against the known noise (``_known_noise_moves``): some ``HOLD_MOVING_DIFFERENCES``
    successive differences moved as the hold asks; every difference beyond ``q`` from the first
    to the last lies on one side along their sum (a vehicle arriving against it, or a state that
    went back, is not one change); the last ``RAMP_MIN_REST`` differences are still (each ``J``
    at most ``q``: the state after has windows); and the still windows' level differs from the
    window before the first moving difference by more than any vehicle, either way
    (``beyond_any_vehicle``: a vehicle driving off over minutes moves as a ramp does). The windows
    between the first moving difference and the last hold neither state; the new state begins
    after them, and the window before them stays the old state's (as ``ramp_windows`` has it). A
    stretch this rule reads where nothing changed needs the hold's four moved differences first,
    whose probability is bounded there, and a level beyond any vehicle after them. Without
    ``one_sign`` the moving differences may lie on either side (a ramp the detector held on past
    ``event_max_pending``, ``ChangeDetector._long_run``: the test car's moves among its windows
    are left out with it).
    """
    d, lag, js, cov, q = _known_noise_moves(y, k, window_cov, phi, probability)
    m = len(d)
    if m < HOLD_MOVING_DIFFERENCES + RAMP_MIN_REST:
        return None
    if not _moved_somewhere(d, lag, js, cov, q):
        return None
    moved = np.flatnonzero(js > q)
    first, last = int(moved[0]), int(moved[-1])
    if m - 1 - last < RAMP_MIN_REST:
        return None  # still moving at the last windows held
    total = d[first : last + 1].sum(axis=0)
    if one_sign and np.any(d[moved] @ np.linalg.solve(cov, total) <= 0.0):
        return None
    y = np.asarray(y, float).reshape(-1, 2)
    if not beyond_any_vehicle(y[last + 1 :].mean(axis=0) - y[first], vehicle_max_n):
        return None
    return first + 1, last + 1


def _moved_somewhere(d: np.ndarray, lag: np.ndarray, js: np.ndarray, cov: np.ndarray, q: float) -> bool:
    """Whether some ``HOLD_MOVING_DIFFERENCES`` successive differences moved (``_moved_block``)."""
    return any(_moved_block(d, lag, js, cov, q, end) for end in range(HOLD_MOVING_DIFFERENCES, len(d) + 1))


def moved_not_still(
    y: np.ndarray, k: np.ndarray, window_cov: np.ndarray, phi: np.ndarray, probability: float
) -> bool:
    """Whether the windows moved somewhere as the hold asks and their last differences are not yet still.

    On the known noise (``_known_noise_moves``): some ``HOLD_MOVING_DIFFERENCES`` successive
    differences moved (``_moved_block``), and of the last ``RAMP_MIN_REST`` one has ``J`` beyond
    ``q``: a ramp whose pace broke (the test car's moves among its windows) that ``moved_then_still``
    cannot read yet.
    """
    d, lag, js, cov, q = _known_noise_moves(y, k, window_cov, phi, probability)
    if len(js) < RAMP_MIN_REST or bool(np.all(js[-RAMP_MIN_REST:] <= q)):
        return False
    return _moved_somewhere(d, lag, js, cov, q)


def ramp_windows(y: np.ndarray, k: np.ndarray, probability: float) -> tuple[int, int] | None:
    """Return ``(first window moving, first window of the new state)`` of a gradual change, or None.

    A support lowered by jacks over minutes (a load-test day's lowering records), or settling over
    minutes, moves the window means a little in every window for a while: no one difference
    dwarfs the others, so neither step rule sees it, and taken as one state the moving windows
    read as noise (the noise model's scale grew 300-fold on a 20 mm lowering over eight minutes of
    a record after a gap, and the day's earlier 10 mm event fell to an unconfirmed change of
    probability 0.12). A *ramp* is a block of at least ``RAMP_MIN_LENGTH`` successive differences
    of one sign along their sum (each ``d_i' P s > 0``), each but its first and last (which may
    hold the ramp's start and end within a window) larger in ``J`` than every difference outside
    it (a support that stood still between two steps is states, not a ramp: the step rules and
    the detector read them), and whose sum, over the block's lag, beats
    ``ramp_ratio`` times every difference outside it (at least ``RAMP_MIN_REST`` of them: the
    states on either side); the block with the largest ratio is taken. Its inner windows hold
    neither state; the new state begins after it. Derivation: ``false_ramp_probability``.
    """
    diffs = _differences(y, k, RAMP_MIN_LENGTH + RAMP_MIN_REST)
    if diffs is None:
        return None
    raw, lag, _, prec, single = diffs
    m = len(raw)
    best, found = 0.0, None
    for length in range(RAMP_MIN_LENGTH, m - RAMP_MIN_REST + 1):
        for a in range(m - length + 1):
            score = _ramp_score(raw, lag, prec, single, (a, a + length), probability)
            if score > best:
                best, found = score, (a + 1, a + length)
    return found


def _differences(
    y: np.ndarray, k: np.ndarray, at_least: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """Successive differences of window means ``y`` (n, 2) at indices ``k``, on their own scale.

    Returns ``raw`` (n-1, 2), ``lag`` (n-1,), ``d = raw / sqrt(lag)``, the robust precision of
    ``d`` and ``J = d' P d`` (n-1,); None with fewer than ``at_least`` differences, a non-finite
    mean, indices not increasing, or no spread.
    """
    y = np.asarray(y, float).reshape(-1, 2)
    lag = np.diff(np.asarray(k, np.int64).reshape(-1)).astype(float)
    if len(y) - 1 < at_least or not np.all(np.isfinite(y)) or not np.all(lag > 0):
        return None
    raw = np.diff(y, axis=0)
    d = raw / np.sqrt(lag)[:, None]
    prec = _robust_precision(d)
    if prec is None:
        return None
    return raw, lag, d, prec, np.einsum("mi,ij,mj->m", d, prec, d)


def _mixed_start(raw: np.ndarray, a: int) -> int:
    """Return the first window of the new state for a step inside window ``a + 1`` (differences a, a+1).

    The mixed window joins the side it is nearer, by its share of the new state along the step
    (which dwarfs the noise), so that it biases the level it joins least.
    """
    total = raw[a] + raw[a + 1]
    share = float(raw[a] @ total) / float(total @ total)
    return a + 1 if share >= 0.5 else a + 2


def _robust_sd(x: np.ndarray) -> float:
    return float(np.median(np.abs(x))) / MAD_NORMAL


def _robust_precision(d: np.ndarray) -> np.ndarray | None:
    """Return the inverse of the robust covariance of differences ``d`` (m, 2), None without spread."""
    s = np.array([_robust_sd(d[:, 0]), _robust_sd(d[:, 1])])
    if not np.all(s > 0):
        return None
    u = d / s
    r = (_robust_sd(u[:, 0] + u[:, 1]) ** 2 - _robust_sd(u[:, 0] - u[:, 1]) ** 2) / 4.0
    # a correlation read off a few differences: near +-1 it is mostly sampling error, and the
    # precision would amplify noise across the channels' common direction; 0.9 caps that at 10x
    r = float(np.clip(r, -MAX_CORRELATION, MAX_CORRELATION))
    corr_inv = np.array([[1.0, -r], [-r, 1.0]]) / (1.0 - r * r)
    return corr_inv / np.outer(s, s)


def warmup_step(y: np.ndarray, k: np.ndarray, probability: float) -> int | None:
    """Return the index of the first window after a step in window means ``y`` (n, 2) N, or None.

    ``k`` (n,): the windows' indices (increasing); ``probability``: the false-step probability
    allowed (``1 - event_trigger_probability``). A difference across ``L`` windows is divided by
    ``sqrt(L)``: the bridge's slow wander grows like a random walk over minutes (the AR(1) jump
    variance ``2 (1 - phi^L) R`` of ``detector`` for ``phi`` near 1), so a level that moved while
    the test car was cut out is not a step for being compared with neighbours a minute apart. A
    step inside a window moves the means on both sides of it in one direction: two neighbouring
    differences of one sign count as one jump (their sum), and the window between them (the one it
    happened in, holding both states) joins the side it is nearer, so that it biases the level it
    joins least; a single odd window makes two differences of opposite signs, no step.
    """
    one = _one_step(y, k, probability)
    return None if one is None else one[0]


def _one_step(y: np.ndarray, k: np.ndarray, probability: float) -> tuple[int, int | None] | None:
    """``warmup_step``'s step as (first window of the new state, the window it happened in or None)."""
    diffs = _differences(y, k, MIN_DIFFERENCES)
    if diffs is None:
        return None
    raw, lag, d, prec, j = diffs
    order = np.argsort(j)
    i, second = int(order[-1]), int(order[-2])
    if abs(i - second) == 1 and float(d[i] @ prec @ d[second]) > 0.0:
        a = min(i, second)  # the two largest are neighbours of one sign: window a + 1 is mixed
        both = (raw[a] + raw[a + 1]) / np.sqrt(lag[a] + lag[a + 1])
        rest = np.delete(j, [a, a + 1])
        if len(rest) and float(both @ prec @ both) > step_ratio(len(j), probability) * float(np.max(rest)):
            return _mixed_start(raw, a), a + 1
    if float(j[i]) > step_ratio(len(j), probability) * float(j[second]):
        return i + 1, None
    return None
